// SPDX-License-Identifier: Apache-2.0
// Raw sets for driver tests and benchmarks: the five read-outs of the default
// schedule, each pixel's charges from a caller's model of its light.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include <tiny_laser_driver/protocol.hpp>

namespace tinyline::tiny_laser_driver::testing {

inline constexpr std::uint16_t kDefaultPulses[5] = {20, 100, 200, 400, 700};

/// Encodes one raw set. `light(pulses, pixel)` returns {sum, k}: the pixel's
/// total charge a + b (charge units) and its ratio k = b / (a + b); the wire
/// carries tenths of a charge unit.
template <class Light>
std::vector<std::uint8_t> encode_synthetic_set(std::uint16_t temperature_decic, Light&& light) {
  std::vector<std::uint8_t> out;
  for (int i = 0; i < 5; ++i) {
    RawFrame f;
    f.index = static_cast<std::uint16_t>(i);
    f.last = i == 4;
    f.pulses = kDefaultPulses[i];
    f.temperature_decic = temperature_decic;
    for (std::size_t p = 0; p < kPixels; ++p) {
      const auto [sum, k] = light(f.pulses, p);
      f.a[p] = static_cast<std::int16_t>(std::lround(10.0 * sum * (1.0 - k)));
      f.b[p] = static_cast<std::int16_t>(std::lround(10.0 * sum * k));
    }
    encode_raw_frame(f, out);
  }
  return out;
}

/// A varied set: ratio and light change with the seed and pixel over the
/// calibrated range, from too dark to saturated at the top read-outs.
inline std::vector<std::uint8_t> varied_set(int seed, std::uint16_t temperature_decic) {
  return encode_synthetic_set(temperature_decic, [seed](std::uint16_t pulses, std::size_t p) {
    const double k = 0.48 + 0.3 * std::fmod(0.37 * seed + 0.011 * p, 1.0);
    const double per_pulse = 0.02 + 0.6 * std::fmod(0.13 * seed + 0.007 * p, 1.0);
    return std::pair{std::min(per_pulse * pulses, 480.0), k};
  });
}

}  // namespace tinyline::tiny_laser_driver::testing
