#pragma once
/// \file A stable least-significant-digit radix sort of indices by integer keys: the particle
/// sort in a sparse box (engine/step/transfer.cpp) and the contacts' sort by patch and id
/// (engine/step/contact.cpp).

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace mpm {

/// Puts the indices 0 .. n - 1 in `order` sorted by key(i), an unsigned integer below 2^bits
/// (equal keys keep index order): passes of a stable counting sort on up to 11 bits each, so
/// the time is in proportion to n. `scratch` is the second array the passes alternate with.
template <class Key>
void radix_order(std::size_t n, int bits, const Key& key, std::vector<std::uint32_t>& order,
                 std::vector<std::uint32_t>& scratch) {
  bits = std::max(bits, 1);
  const int passes = (bits + 10) / 11, digit = (bits + passes - 1) / passes;
  const std::uint64_t mask = (std::uint64_t{1} << digit) - 1;
  order.resize(n);
  scratch.resize(n);
  // The passes alternate between the two arrays and end in `order`; the first reads the
  // indices in order.
  std::uint32_t* src = nullptr;
  std::uint32_t* dst = passes % 2 ? order.data() : scratch.data();
  std::array<std::uint32_t, std::size_t{1} << 11> digits;  // on the stack: no allocation
  const std::span<std::uint32_t> at(digits.data(), std::size_t{1} << digit);
  for (int pass = 0, shift = 0; pass < passes; ++pass, shift += digit) {
    const auto index = [&](std::size_t j) { return src ? src[j] : static_cast<std::uint32_t>(j); };
    const auto bucket = [&](std::uint32_t i) {
      return (static_cast<std::uint64_t>(key(i)) >> shift) & mask;
    };
    std::fill(at.begin(), at.end(), 0u);
    for (std::size_t j = 0; j < n; ++j) ++at[bucket(index(j))];
    std::uint32_t end = 0;
    for (std::uint32_t& a : at) end += std::exchange(a, end);
    for (std::size_t j = 0; j < n; ++j) {
      const std::uint32_t i = index(j);
      dst[at[bucket(i)]++] = i;
    }
    src = dst;
    dst = dst == scratch.data() ? order.data() : scratch.data();
  }
}

}  // namespace mpm
