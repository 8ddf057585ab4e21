#pragma once
/// \file Running a piece of work in a forked child, so its time and peak memory are its own.

#include <functional>
#include <string>

namespace mpm {

/// Runs `work` in a forked child process and returns the text it returned. The child's peak
/// memory does not include the parent's. Throws std::runtime_error naming `what` if the child
/// throws, crashes or returns nothing. Call it from a process that has not yet run an OpenMP
/// parallel region: libgomp's thread pool does not survive fork, and a child that starts a
/// parallel region after the parent has one waits forever (`mpm bench` and `mpm study` fork
/// before any; a test program must give such a test a process of its own, as ctest does).
std::string run_in_child(const std::function<std::string()>& work, const std::string& what);

/// Peak resident memory of the calling process so far, bytes.
double peak_rss_bytes();

}  // namespace mpm
