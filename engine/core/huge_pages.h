#pragma once
/// \file Transparent huge pages for the heap, where the particle and grid arrays live.

#include <cstdint>
#include <fstream>
#include <string>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace mpm {

/// Asks the kernel to back the heap's whole 2 MiB pages with transparent huge pages: the ones
/// in use now (MADV_COLLAPSE, Linux 6.1 and later) and those faulted later (MADV_HUGEPAGE).
/// A substep walks tens of MB of particle, grid and sort arrays, which with 4 KiB pages need
/// thousands of TLB entries; glibc's malloc puts them in the heap. Where the kernel refuses
/// (older kernels, THP off), nothing changes; contents never do. A no-op off Linux.
inline void advise_heap_huge_pages() {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  constexpr std::uintptr_t kHuge = std::uintptr_t(1) << 21;
  constexpr int kCollapse = 25;  // MADV_COLLAPSE, not yet in every libc's headers
  std::ifstream maps("/proc/self/maps");
  for (std::string line; std::getline(maps, line);) {
    if (line.find("[heap]") == std::string::npos) continue;
    const std::size_t dash = line.find('-');
    const std::uintptr_t first = std::stoull(line.substr(0, dash), nullptr, 16);
    const std::uintptr_t last = std::stoull(line.substr(dash + 1), nullptr, 16);
    const std::uintptr_t begin = (first + kHuge - 1) & ~(kHuge - 1), end = last & ~(kHuge - 1);
    if (end <= begin) return;
    void* const p = reinterpret_cast<void*>(begin);
    madvise(p, end - begin, MADV_HUGEPAGE);
    madvise(p, end - begin, kCollapse);
    return;
  }
#endif
}

}  // namespace mpm
