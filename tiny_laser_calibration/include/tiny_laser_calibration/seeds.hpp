// Which seeds may be used for what. Settings of the residual loop (alpha, the
// gain margin, knots, the candidate set) and the tests are tuned on the
// tuning seeds; the figures the docs report (null rate, detection rates) come
// from the held-out seeds, which no setting was ever chosen on. The sweep
// (calibration_discovery_sweep) refuses a range that mixes the two.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace tinyline::tiny_laser_calibration {

struct SeedRange {
  std::uint64_t first = 0, last = 0;  ///< inclusive
  [[nodiscard]] constexpr bool contains(std::uint64_t s) const { return s >= first && s <= last; }
  [[nodiscard]] constexpr bool contains(const SeedRange& r) const { return r.first <= r.last && contains(r.first) && contains(r.last); }
};

inline constexpr SeedRange kTuningSeeds{1, 999};
inline constexpr SeedRange kHeldOutSeeds{1000, 1999};

enum class SeedUse { kTuning, kHeldOut };
[[nodiscard]] constexpr std::string_view to_string(SeedUse u) { return u == SeedUse::kTuning ? "tuning" : "held-out"; }

/// The use a whole range belongs to; nullopt when it mixes the two or leaves both.
[[nodiscard]] constexpr std::optional<SeedUse> seed_use(const SeedRange& r) {
  if (kTuningSeeds.contains(r)) return SeedUse::kTuning;
  if (kHeldOutSeeds.contains(r)) return SeedUse::kHeldOut;
  return std::nullopt;
}

}  // namespace tinyline::tiny_laser_calibration
