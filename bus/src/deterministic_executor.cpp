// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/executor.hpp>

#include <stdexcept>

#include "executor_internal.hpp"

namespace tinyline::bus {

using detail::CoreScope;

DeterministicExecutor::DeterministicExecutor(Clock& clock) : Executor(clock, ExecutorOptions{1, Duration::zero(), 1}) {
  if (!clock.is_sim()) throw std::invalid_argument("DeterministicExecutor needs a context with a sim clock");
  unbounded_ = true;
  core_->fifo = true;
}

std::size_t DeterministicExecutor::spin_until_idle() {
  start_pending_nodes();
  CoreScope scope(core_.get());
  std::size_t n = 0;
  while (true) {
    std::shared_ptr<CallbackGroup> g;
    {
      std::lock_guard lk(core_->mu);
      if (core_->ready.empty()) break;
      g = std::move(core_->ready.front());
      core_->ready.pop_front();
    }
    g->scheduled_.store(false, std::memory_order_seq_cst);
    std::size_t ran = 0;
    g->try_run(1, &ran);
    n += ran;
    // A publisher that saw the group running left the re-queueing to us.
    if (g->core_raw_.load(std::memory_order_acquire) == core_.get() && !g->dead() && g->has_work() &&
        !g->scheduled_.exchange(true, std::memory_order_seq_cst)) {
      std::lock_guard lk(core_->mu);
      core_->ready.push_back(g);
    }
  }
  return n;
}

void DeterministicExecutor::advance_to(Time t) {
  start_pending_nodes();
  spin_until_idle();
  if (!clock_.started() || t < clock_.now()) {
    // First time (timers start counting here), or a jump back (loop): re-anchor.
    clock_.set_sim_time(t);
    std::lock_guard lk(timers_mu_);
    for (auto& [tm, g] : timers_) {
      tm->next_due_ = t + tm->period_;
      tm->anchored_ = true;
    }
  }
  while (true) {
    std::vector<std::pair<std::shared_ptr<Timer>, std::shared_ptr<CallbackGroup>>> due;
    std::optional<Time> earliest;
    {
      std::lock_guard lk(timers_mu_);
      std::erase_if(timers_, [](const auto& p) { return p.first->cancelled(); });
      const Time now = clock_.now();
      for (auto& [tm, g] : timers_) {
        if (!tm->anchored_) {
          tm->next_due_ = now + tm->period_;
          tm->anchored_ = true;
        }
        if (!earliest || tm->next_due_ < *earliest) earliest = tm->next_due_;
      }
      if (!earliest || *earliest > t) break;
      for (auto& [tm, g] : timers_) {
        if (tm->next_due_ == *earliest) {
          due.emplace_back(tm, g);
          tm->next_due_ += tm->period_;
        }
      }
    }
    clock_.set_sim_time(*earliest);
    for (auto& [tm, g] : due) g->notify(tm);
    spin_until_idle();
  }
  if (clock_.now() != t) clock_.set_sim_time(t);
  spin_until_idle();
}

void DeterministicExecutor::spin() { spin_until_idle(); }

}  // namespace tinyline::bus
