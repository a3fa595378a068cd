// Reproducible randomness for the cores (splitmix64): the same sequence for
// a seed on every platform, unlike the standard distributions.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

namespace tinyline::tomato_reasoning::detail {

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : s_(seed * 0x9e3779b97f4a7c15ULL + 0x632be59bd9b4e019ULL) {}
  std::uint64_t next() {
    std::uint64_t z = (s_ += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  /// Uniform in (0, 1).
  double uniform() { return (static_cast<double>(next() >> 11) + 0.5) * 0x1.0p-53; }
  /// Uniform index in [0, n).
  std::size_t index(std::size_t n) {
    const std::size_t k = static_cast<std::size_t>(uniform() * static_cast<double>(n));
    return k < n ? k : n - 1;
  }
  /// Standard normal (Box-Muller).
  double normal() { return std::sqrt(-2.0 * std::log(uniform())) * std::cos(2.0 * M_PI * uniform()); }

 private:
  std::uint64_t s_;
};

}  // namespace tinyline::tomato_reasoning::detail
