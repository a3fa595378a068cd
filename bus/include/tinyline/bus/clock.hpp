// SPDX-License-Identifier: Apache-2.0
// The clock of a context: wall time, or sim time set by bag replay. Timers
// follow it; executors listen for sim-time updates.
#pragma once

#include <atomic>
#include <functional>
#include <mutex>
#include <vector>

#include <tinyline/bus/time.hpp>

namespace tinyline::bus {

enum class ClockType { Wall, Sim };

class Clock {
 public:
  explicit Clock(ClockType type = ClockType::Wall) : type_(type) {}
  Clock(const Clock&) = delete;
  Clock& operator=(const Clock&) = delete;

  ClockType type() const { return type_; }
  bool is_sim() const { return type_ == ClockType::Sim; }

  /// Wall: the system clock. Sim: the last time set (0 until the first set).
  Time now() const;

  /// True once sim time has been set (always true for wall time).
  bool started() const { return !is_sim() || started_.load(std::memory_order_acquire); }
  /// Sim: the first time ever set (timers created before it count from it).
  Time start_time() const { return Time{start_ns_.load(std::memory_order_acquire)}; }

  /// Sets sim time and wakes every listener. Only valid for a sim clock.
  void set_sim_time(Time t);

  /// Called (from the setter's thread) after every sim-time change.
  int add_listener(std::function<void()> fn);
  void remove_listener(int id);

 private:
  ClockType type_;
  std::atomic<std::int64_t> sim_ns_{0};
  std::atomic<bool> started_{false};
  std::atomic<std::int64_t> start_ns_{0};
  std::mutex mu_;
  std::vector<std::pair<int, std::function<void()>>> listeners_;
  int next_id_ = 1;
};

}  // namespace tinyline::bus
