// SPDX-License-Identifier: Apache-2.0
// Time on the bus: nanoseconds since the epoch (wall clock) or since the
// start of a recording (sim time driven by bag replay).
#pragma once

#include <chrono>
#include <compare>
#include <cstdint>

#include <tinyline/msg/builtin_interfaces/time.hpp>

namespace tinyline::bus {

using Duration = std::chrono::nanoseconds;

struct Time {
  std::int64_t ns = 0;

  static constexpr Time from_ns(std::int64_t n) { return Time{n}; }
  static Time from_seconds(double s) { return Time{static_cast<std::int64_t>(s * 1e9)}; }
  static Time from_msg(const builtin_interfaces::msg::Time& t) {
    return Time{static_cast<std::int64_t>(t.sec) * 1'000'000'000 + t.nanosec};
  }
  double seconds() const { return static_cast<double>(ns) * 1e-9; }
  builtin_interfaces::msg::Time to_msg() const {
    builtin_interfaces::msg::Time t;
    std::int64_t s = ns / 1'000'000'000;
    std::int64_t r = ns % 1'000'000'000;
    if (r < 0) {
      r += 1'000'000'000;
      --s;
    }
    t.sec = static_cast<std::int32_t>(s);
    t.nanosec = static_cast<std::uint32_t>(r);
    return t;
  }

  auto operator<=>(const Time&) const = default;
  Time operator+(Duration d) const { return Time{ns + d.count()}; }
  Time operator-(Duration d) const { return Time{ns - d.count()}; }
  Duration operator-(Time o) const { return Duration{ns - o.ns}; }
  Time& operator+=(Duration d) {
    ns += d.count();
    return *this;
  }
};

inline double to_seconds(Duration d) { return std::chrono::duration<double>(d).count(); }
inline Duration from_seconds(double s) {
  return std::chrono::duration_cast<Duration>(std::chrono::duration<double>(s));
}

}  // namespace tinyline::bus
