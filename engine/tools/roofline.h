#pragma once
/// \file What this machine can do at most: peak floating-point rate and memory bandwidth,
/// measured by small kernels, for the roofline in docs/performance.md.

#include <string>

namespace mpm {

/// Peak figures of this machine, measured with `threads` threads.
struct MachinePeaks {
  int threads = 0;               ///< Threads used (one per core on this machine).
  std::string simd_target;       ///< Highway's instruction set chosen at run time, e.g. AVX3.
  int float_lanes = 0;           ///< float lanes of one vector on that target.
  double float_gflops = 0;       ///< Fused multiply-adds in float, 2 flops each, GFLOP/s.
  double double_gflops = 0;      ///< The same in double, GFLOP/s.
  double scalar_double_gflops = 0;  ///< Scalar double multiply-adds (no SIMD), GFLOP/s.
  double triad_gbytes = 0;       ///< STREAM triad a = b + s c over arrays far larger than the
                                 ///< caches, counting 24 bytes per element as STREAM does, GB/s.
};

/// Measures the peaks: independent chains of vector fused multiply-adds per thread (enough to
/// hide the latency of both FMA pipes), and the triad over 3 x 256 MB; each the best of
/// `repeats`. `threads` 0 means all cores.
MachinePeaks measure_machine_peaks(int threads = 0, int repeats = 5);

/// The peaks as text lines for `mpm bench --cases machine`.
std::string format_machine_peaks(const MachinePeaks& peaks);

}  // namespace mpm
