#pragma once
/// \file Running a piece of work in a forked child, so its time and peak memory are its own.

#include <functional>
#include <string>

namespace mpm {

/// Runs `work` in a forked child process and returns the text it returned. The child's peak
/// memory does not include the parent's. Throws std::runtime_error naming `what` if the child
/// throws, crashes or returns nothing.
std::string run_in_child(const std::function<std::string()>& work, const std::string& what);

/// Peak resident memory of the calling process so far, bytes.
double peak_rss_bytes();

}  // namespace mpm
