// SPDX-License-Identifier: Apache-2.0
// The project's one random generator: the same numbers for a seed on every
// platform and standard library (the standard distributions promise no
// such thing), so that seeded tests, scenes and evaluations reproduce.
//
//   splitmix64(x)        a 64-bit hash (counter-based randomness: one draw per key)
//   mix_seed(s, t, i)    a seed for stream (tag t, index i) of seed s
//   stream_seed(s, salt) spreads small seeds over the state space
//   SplitMix64           the engine for a few draws per seed
//   Xoshiro256StarStar   the engine for long streams (the sensor's noise)
//   Random<Engine>       uniform, integer and normal draws on either engine
//                        (SplitMixRandom, XoshiroRandom)
//
// Both engines and every draw are the algorithms the packages used before
// they shared this file: outputs are bit for bit the same.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>

namespace tinyline::common {

/// 2^64 / golden ratio, splitmix64's increment.
inline constexpr std::uint64_t kGoldenGamma = 0x9e3779b97f4a7c15ULL;

/// splitmix64's output for the state after x: a 64-bit hash of x in which
/// every input bit affects every output bit.
[[nodiscard]] constexpr std::uint64_t splitmix64(std::uint64_t x) {
  x += kGoldenGamma;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// A seed for one stream: a seed, a purpose tag, an index (a sensor's
/// noise for read-out `index`), so that streams do not depend on the order
/// in which they are made.
[[nodiscard]] constexpr std::uint64_t mix_seed(std::uint64_t seed, std::uint64_t tag, std::uint64_t index) {
  return splitmix64(splitmix64(splitmix64(seed) ^ tag) ^ index);
}

/// An engine state from a small seed and a per-purpose salt: seeds 1, 2, 3
/// start far apart, and two purposes with the same seed differ.
[[nodiscard]] constexpr std::uint64_t stream_seed(std::uint64_t seed, std::uint64_t salt) {
  return seed * kGoldenGamma + salt;
}

/// Uniform in [0, 1) from the top 53 bits.
[[nodiscard]] constexpr double unit_closed_open(std::uint64_t bits) {
  return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

/// Uniform in (0, 1] from the top 53 bits: never 0, so log() of it is
/// finite. (k + 0.5 rounds to even above 2^52: the top value gives 1.0.)
[[nodiscard]] constexpr double unit_open(std::uint64_t bits) {
  return (static_cast<double>(bits >> 11) + 0.5) * 0x1.0p-53;
}

/// splitmix64 as a stream: the state advances by the golden gamma.
class SplitMix64 {
 public:
  explicit constexpr SplitMix64(std::uint64_t state) : s_(state) {}
  constexpr std::uint64_t operator()() {
    const std::uint64_t z = splitmix64(s_);
    s_ += kGoldenGamma;
    return z;
  }

 private:
  std::uint64_t s_;
};

/// xoshiro256** (Blackman and Vigna), its state filled from splitmix64.
class Xoshiro256StarStar {
 public:
  explicit constexpr Xoshiro256StarStar(std::uint64_t seed) {
    SplitMix64 fill(seed);
    for (auto& w : s_) w = fill();
  }
  constexpr std::uint64_t operator()() {
    const std::uint64_t r = rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return r;
  }

 private:
  static constexpr std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  std::uint64_t s_[4] = {};
};

/// Draws on an engine.
template <class Engine>
class Random {
 public:
  explicit constexpr Random(std::uint64_t seed) : engine_(seed) {}

  std::uint64_t next() { return engine_(); }
  /// Uniform in [0, 1).
  double uniform() { return unit_closed_open(next()); }
  /// Uniform in (0, 1] (see unit_open).
  double uniform_open() { return unit_open(next()); }
  /// Uniform integer in [0, n), n > 0, exactly (the short last block of
  /// 2^64 is rejected).
  std::uint64_t below(std::uint64_t n) {
    const std::uint64_t threshold = (0 - n) % n;  // 2^64 mod n
    for (;;) {
      const std::uint64_t r = next();
      if (r >= threshold) return r % n;
    }
  }
  /// Index in [0, n), n > 0, from one open uniform (one draw, a bias of
  /// order n / 2^53).
  std::size_t index(std::size_t n) {
    const auto k = static_cast<std::size_t>(uniform_open() * static_cast<double>(n));
    return k < n ? k : n - 1;
  }
  /// Standard normal, Box-Muller on [0, 1) uniforms: the pair's second value
  /// is kept for the next call.
  double normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u1 = uniform();
    while (u1 <= 0.0) u1 = uniform();
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(2.0 * std::numbers::pi * u2);
    has_spare_ = true;
    return r * std::cos(2.0 * std::numbers::pi * u2);
  }
  /// Standard normal, Box-Muller on two unit_open uniforms per value (no
  /// state kept between calls).
  double normal_unpaired() {
    const double u1 = uniform_open();
    const double u2 = uniform_open();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }

 private:
  Engine engine_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

/// A few draws per seed (trials, scenes, RANSAC samples).
using SplitMixRandom = Random<SplitMix64>;
/// Long streams (a sensor's noise).
using XoshiroRandom = Random<Xoshiro256StarStar>;

}  // namespace tinyline::common
