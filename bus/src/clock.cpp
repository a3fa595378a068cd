// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/clock.hpp>

#include <stdexcept>

namespace tinyline::bus {

Time Clock::now() const {
  if (is_sim()) return Time{sim_ns_.load(std::memory_order_acquire)};
  return Time{std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
                  .count()};
}

void Clock::set_sim_time(Time t) {
  if (!is_sim()) throw std::logic_error("set_sim_time on a wall clock");
  sim_ns_.store(t.ns, std::memory_order_release);
  if (!started_.load(std::memory_order_acquire)) start_ns_.store(t.ns, std::memory_order_release);
  started_.store(true, std::memory_order_release);
  std::vector<std::function<void()>> fns;
  {
    std::lock_guard lk(mu_);
    for (auto& [id, fn] : listeners_) fns.push_back(fn);
  }
  for (auto& fn : fns) fn();
}

int Clock::add_listener(std::function<void()> fn) {
  std::lock_guard lk(mu_);
  listeners_.emplace_back(next_id_, std::move(fn));
  return next_id_++;
}

void Clock::remove_listener(int id) {
  std::lock_guard lk(mu_);
  std::erase_if(listeners_, [id](const auto& p) { return p.first == id; });
}

}  // namespace tinyline::bus
