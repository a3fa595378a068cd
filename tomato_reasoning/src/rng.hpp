// Reproducible randomness for the cores (splitmix64): the same sequence for
// a seed on every platform, unlike the standard distributions.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

namespace tinyline::tomato_reasoning::detail {

/// One splitmix64 step as a hash: the same key gives the same bits everywhere
/// (counter-based randomness, e.g. one draw per trial and seed).
inline std::uint64_t mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}
/// Uniform in (0, 1) from the top 53 bits of a hash.
inline double unit_uniform(std::uint64_t bits) { return (static_cast<double>(bits >> 11) + 0.5) * 0x1.0p-53; }

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : s_(seed * 0x9e3779b97f4a7c15ULL + 0x632be59bd9b4e019ULL) {}
  std::uint64_t next() {
    const std::uint64_t z = mix(s_);
    s_ += 0x9e3779b97f4a7c15ULL;
    return z;
  }
  /// Uniform in (0, 1).
  double uniform() { return unit_uniform(next()); }
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
