#include "engine/tools/roofline.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>

// Highway compiles the FMA kernels once per instruction set and picks the best at run time,
// as the SIMD transfers do (engine/step/simd/transfer_simd.cpp), so the peak is the one those
// transfers can reach.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "engine/tools/roofline.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace mpm::roofline {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

/// `iters` rounds of 12 independent FMA chains on full vectors of T; returns the flops done
/// (2 per lane per FMA) and writes a sum so nothing is optimised away.
template <class T>
double fma_chains(long iters, double* sink) {
  const hn::ScalableTag<T> d;
  constexpr int kChains = 12;  // FMA latency 4 x 2 pipes, with room to spare
  auto a = hn::Set(d, T(0.999999)), b = hn::Set(d, T(1e-7));
  hn::Vec<decltype(d)> acc[kChains];
  for (int c = 0; c < kChains; ++c) acc[c] = hn::Set(d, T(c));
  for (long i = 0; i < iters; ++i)
    for (int c = 0; c < kChains; ++c) acc[c] = hn::MulAdd(acc[c], a, b);
  auto s = acc[0];
  for (int c = 1; c < kChains; ++c) s = hn::Add(s, acc[c]);
  *sink += static_cast<double>(hn::GetLane(s));
  return 2.0 * kChains * hn::Lanes(d) * static_cast<double>(iters);
}

double FmaFloat(long iters, double* sink) { return fma_chains<float>(iters, sink); }
double FmaDouble(long iters, double* sink) { return fma_chains<double>(iters, sink); }
int FloatLanes() { return static_cast<int>(hn::Lanes(hn::ScalableTag<float>())); }
const char* TargetName() { return hwy::TargetName(HWY_TARGET); }

}  // namespace HWY_NAMESPACE
}  // namespace mpm::roofline
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace mpm {

namespace roofline {
HWY_EXPORT(FmaFloat);
HWY_EXPORT(FmaDouble);
HWY_EXPORT(FloatLanes);
HWY_EXPORT(TargetName);

// Dispatched from inside this namespace: with a single target (a -march=native build whose
// baseline is the best target) HWY_DYNAMIC_DISPATCH names the target's namespace directly, which
// exists only in here (roofline::N_AVX3_DL, not N_AVX3_DL::roofline).

/// FmaFloat on the best target the CPU runs.
double fma_float(long iters, double* sink) {
  return HWY_DYNAMIC_DISPATCH(FmaFloat)(iters, sink);
}
/// FmaDouble on the best target the CPU runs.
double fma_double(long iters, double* sink) {
  return HWY_DYNAMIC_DISPATCH(FmaDouble)(iters, sink);
}
/// The name of the best target the CPU runs.
const char* target_name() {
  return HWY_DYNAMIC_DISPATCH(TargetName)();
}
/// Float lanes of a full vector on the best target the CPU runs.
int float_lanes() {
  return HWY_DYNAMIC_DISPATCH(FloatLanes)();
}
}  // namespace roofline

namespace {

using Clock = std::chrono::steady_clock;

/// Best GFLOP/s over `repeats` of `kernel` run on every thread at once.
template <class Kernel>
double best_gflops(Kernel kernel, long iters, int repeats) {
  double best = 0, sink = 0;
  for (int r = 0; r < repeats; ++r) {
    double flops = 0;
    const auto t0 = Clock::now();
#pragma omp parallel reduction(+ : flops, sink)
    flops += kernel(iters, &sink);
    const double s = std::chrono::duration<double>(Clock::now() - t0).count();
    best = std::max(best, flops / s / 1e9);
  }
  if (sink == 12345.678) std::puts("");  // keeps the sums alive
  return best;
}

/// Scalar double chains (no vector lanes): what code the compiler leaves scalar can reach.
double scalar_chains(long iters, double* sink) {
  constexpr int kChains = 12;
  volatile double seed = 0.999999;
  const double a = seed, b = 1e-7;
  double acc[kChains];
  for (int c = 0; c < kChains; ++c) acc[c] = c;
  for (long i = 0; i < iters; ++i)
#pragma GCC unroll 12
    for (int c = 0; c < kChains; ++c) acc[c] = acc[c] * a + b;
  double s = 0;
  for (double v : acc) s += v;
  *sink += s;
  return 2.0 * kChains * static_cast<double>(iters);
}

/// Best STREAM triad bandwidth over `repeats`, GB/s (24 bytes per element).
double triad_bandwidth(int repeats) {
  const long n = 32L << 20;  // 3 x 256 MB of doubles: far beyond any cache
  std::vector<double> a(n), b(n), c(n);
#pragma omp parallel for schedule(static)
  for (long i = 0; i < n; ++i) a[i] = 0, b[i] = 1.0, c[i] = 2.0;  // first touch by the users
  double best = 0;
  for (int r = 0; r < repeats; ++r) {
    const double s = 0.5 + r;
    const auto t0 = Clock::now();
#pragma omp parallel for schedule(static)
    for (long i = 0; i < n; ++i) a[i] = b[i] + s * c[i];
    const double sec = std::chrono::duration<double>(Clock::now() - t0).count();
    best = std::max(best, 24.0 * n / sec / 1e9);
  }
  if (a[n / 2] == 12345.678) std::puts("");
  return best;
}

}  // namespace

MachinePeaks measure_machine_peaks(int threads, int repeats) {
  const int saved = omp_get_max_threads();
  if (threads > 0) omp_set_num_threads(threads);
  MachinePeaks p;
  p.threads = omp_get_max_threads();
  p.simd_target = roofline::target_name();
  p.float_lanes = roofline::float_lanes();
  const long iters = 20000000;
  p.float_gflops = best_gflops(roofline::fma_float, iters, repeats);
  p.double_gflops = best_gflops(roofline::fma_double, iters, repeats);
  p.scalar_double_gflops = best_gflops(scalar_chains, iters, repeats);
  p.triad_gbytes = triad_bandwidth(repeats);
  omp_set_num_threads(saved);
  return p;
}

std::string format_machine_peaks(const MachinePeaks& p) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "machine peaks, %d threads, SIMD target %s (%d float lanes), best of 5:\n"
                "  float FMA        %8.1f GFLOP/s\n"
                "  double FMA       %8.1f GFLOP/s\n"
                "  scalar double    %8.1f GFLOP/s\n"
                "  memory (triad)   %8.1f GB/s\n",
                p.threads, p.simd_target.c_str(), p.float_lanes, p.float_gflops, p.double_gflops,
                p.scalar_double_gflops, p.triad_gbytes);
  return buf;
}

}  // namespace mpm
#endif  // HWY_ONCE
