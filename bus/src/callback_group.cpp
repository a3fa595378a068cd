// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/executor.hpp>

#include <sys/resource.h>

#include <algorithm>

#include <tinyline/bus/graph.hpp>
#include <tinyline/bus/node.hpp>

#include "executor_internal.hpp"

namespace tinyline::bus {

using detail::CoreScope;
using detail::tl_core;

namespace {
// Set while this thread runs callbacks inline (an InlineRunner's thread). A
// callback's publish may come back to this thread (Cyclone delivers to
// readers of its own process on the writer's thread): that one is queued for
// the runner or the workers, so two graphs replying to each other cannot
// recurse without end.
thread_local bool tl_running_inline = false;

// Inline runs hold up the runner every transport hands its messages to (and
// a run that outlives the runner's bound costs a fresh thread): callbacks
// that take longer than this, several times in a row, go back to the workers
// for a while. The runs of a message or two on the way through a graph take a few
// microseconds; large messages take longer but are copy-bound anyway.
constexpr auto kInlineBudget = std::chrono::microseconds(200);
constexpr int kSlowInlineRuns = 3;
constexpr auto kInlinePause = std::chrono::seconds(1);
// One inline run this long in which the thread went to sleep: the callbacks
// block (a full pipe, a lock, a disk). They run on workers for good, where
// blocking holds up only their own node. A run this long without sleeping lost
// its core (load, a sanitizer): only a slow run.
constexpr auto kInlineStall = std::chrono::milliseconds(20);
// Callbacks in a row within kInlineBudget before a group may run inline: a
// callback that blocks on its first runs blocks a worker, not the transport.
constexpr int kProvenRuns = 8;
constexpr std::size_t kInlineBatch = 8;
// Callbacks a waiting reliable publisher runs for the full subscriber per
// turn: enough to make room, few enough to go back to its own message soon.
constexpr std::size_t kHelpBatch = 16;

// Times this thread went to sleep so far (voluntary context switches). A
// thread that only lost its core to another is switched involuntarily.
long voluntary_waits() {
  rusage u{};
  getrusage(RUSAGE_THREAD, &u);
  return u.ru_nvcsw;
}

std::int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}
}  // namespace

void CallbackGroup::announce() {
  detail::ExecutorCore* core = core_raw_.load(std::memory_order_acquire);
  if (core == nullptr) return;
  if (!core->fifo) {
    if (!InlineDelivery::defer(*this)) core->wake();
    return;
  }
  // Deterministic: enter the FIFO unless already in it or running (the
  // executor re-queues a group that still has work after its turn).
  if (running_.load(std::memory_order_seq_cst) || scheduled_.exchange(true, std::memory_order_seq_cst)) return;
  auto self = shared_from_this();
  std::lock_guard lk(core->mu);
  if (core_raw_.load(std::memory_order_acquire) == core) {
    core->ready.push_back(std::move(self));
  } else {
    scheduled_.store(false);  // detached meanwhile
  }
}

void CallbackGroup::notify(const std::shared_ptr<Timer>& timer) {
  {
    std::lock_guard lk(mu_);
    if (dead()) return;
    ticks_.push_back(Tick{next_stamp(), timer});
    ticks_size_.fetch_add(1, std::memory_order_seq_cst);  // seq_cst: see MessageRing::try_push
  }
  announce();
}

void CallbackGroup::add_subscription(const std::shared_ptr<SubscriptionBase>& s) {
  std::lock_guard lk(mu_);
  if (dead()) return;
  auto next = std::make_shared<SubList>(*subs_);
  next->push_back(s);
  subs_ = std::move(next);
  subs_version_.fetch_add(1, std::memory_order_release);
}

void CallbackGroup::remove_subscription(const SubscriptionBase* s) {
  std::shared_ptr<const SubList> old;  // released outside the lock: it may hold the last reference
  std::lock_guard lk(mu_);
  auto next = std::make_shared<SubList>();
  for (const auto& x : *subs_)
    if (x.get() != s) next->push_back(x);
  if (next->size() == subs_->size()) return;
  old = std::exchange(subs_, std::move(next));
  subs_version_.fetch_add(1, std::memory_order_release);
}

std::shared_ptr<const CallbackGroup::SubList> CallbackGroup::subscriptions(std::uint64_t* version) const {
  std::lock_guard lk(mu_);
  if (version) *version = subs_version_.load(std::memory_order_relaxed);
  return subs_;
}

bool CallbackGroup::has_work(const SubList& subs) const {
  if (ticks_size_.load(std::memory_order_seq_cst) != 0) return true;
  for (const auto& s : subs)
    if (s->front_stamp()) return true;
  return false;
}

bool CallbackGroup::try_run(std::size_t max, std::size_t* ran, const SubList* subs) {
  return claim_and_run(max, ran, subs, false);
}

bool CallbackGroup::try_run_after_stop(std::size_t max, std::size_t* ran) {
  return claim_and_run(max, ran, nullptr, true);
}

bool CallbackGroup::claim_and_run(std::size_t max, std::size_t* ran, const SubList* subs, bool after_stop) {
  bool expected = false;
  if (!running_.compare_exchange_strong(expected, true, std::memory_order_acq_rel)) return false;
  running_thread_.store(std::this_thread::get_id());
  std::shared_ptr<const SubList> own;
  if (subs == nullptr) {
    own = subscriptions();
    subs = own.get();
  }
  const std::size_t n = run_claimed(max, *subs, after_stop);
  running_thread_.store(std::thread::id{});
  running_.store(false, std::memory_order_seq_cst);
  if (shutdown_waiting_.load(std::memory_order_seq_cst)) {
    std::lock_guard lk(mu_);
    idle_.notify_all();
  }
  if (ran) *ran = n;
  return true;
}

bool CallbackGroup::run_for_waiting_publisher() {
  const detail::ExecutorCore* core = core_raw_.load(std::memory_order_acquire);
  // Only a thread of the group's own executor (its callbacks stay on those
  // threads), never one running callbacks inline for a transport.
  if (core == nullptr || core != tl_core || core->fifo || tl_running_inline || running_here()) return false;
  std::size_t ran = 0;
  return try_run(kHelpBatch, &ran) && ran > 0;
}

bool CallbackGroup::proven() const { return short_runs_.load(std::memory_order_relaxed) >= kProvenRuns; }

bool CallbackGroup::accepts_inline() const {
  if (inline_refused_.load(std::memory_order_relaxed) || !proven()) return false;
  const std::int64_t until = inline_paused_until_ns_.load(std::memory_order_relaxed);
  return until == 0 || steady_ns() >= until;
}

bool CallbackGroup::may_run_inline() const {
  const detail::ExecutorCore* core = core_raw_.load(std::memory_order_acquire);
  return core != nullptr && !core->fifo && core->workers.load(std::memory_order_seq_cst) != 0 &&
         !core->stopping.load(std::memory_order_seq_cst) && !dead() && accepts_inline();
}

bool CallbackGroup::try_run_inline() {
  if (tl_running_inline || !may_run_inline()) return false;
  detail::ExecutorCore* core = core_raw_.load(std::memory_order_acquire);
  if (core == nullptr) return false;  // detached meanwhile
  CoreScope scope(core);              // current_executor() inside the callbacks, as on a worker
  const long waits_before = voluntary_waits();
  const auto start = std::chrono::steady_clock::now();
  tl_running_inline = true;
  inline_since_ns_.store(steady_ns(), std::memory_order_relaxed);
  const bool ran = try_run(kInlineBatch);
  inline_since_ns_.store(0, std::memory_order_relaxed);
  tl_running_inline = false;
  if (!ran) return false;
  const auto took = std::chrono::steady_clock::now() - start;
  note_inline_run(took, took >= kInlineStall && voluntary_waits() > waits_before);
  // Work that came meanwhile (or beyond the batch) announced itself to a
  // group that was running; make sure a worker looks.
  if (has_work()) core->wake();
  return true;
}

std::chrono::nanoseconds CallbackGroup::inline_run_time() const {
  const std::int64_t since = inline_since_ns_.load(std::memory_order_relaxed);
  return std::chrono::nanoseconds(since == 0 ? 0 : std::max<std::int64_t>(0, steady_ns() - since));
}

void CallbackGroup::note_inline_run(std::chrono::steady_clock::duration took, bool waited) {
  if (waited) {
    stop_inline();
    return;
  }
  if (took <= kInlineBudget) {
    slow_inline_runs_.store(0, std::memory_order_relaxed);
    return;
  }
  // One slow run is often just the thread losing its core; several in a row
  // are the callbacks themselves.
  if (slow_inline_runs_.fetch_add(1, std::memory_order_relaxed) + 1 < kSlowInlineRuns) return;
  slow_inline_runs_.store(0, std::memory_order_relaxed);
  inline_paused_until_ns_.store(steady_ns() + std::chrono::nanoseconds(kInlinePause).count(),
                                std::memory_order_relaxed);
}

void CallbackGroup::note_run(std::chrono::steady_clock::duration took) {
  // One writer at a time (the group's running thread): load and store suffice.
  const int n = short_runs_.load(std::memory_order_relaxed);
  short_runs_.store(took <= kInlineBudget ? std::min(n + 1, kProvenRuns) : 0, std::memory_order_relaxed);
}

template <class F>
void CallbackGroup::guarded(F&& f) {
  // Proven groups skip the clock: the inline run's own timing watches them.
  const bool timed = !proven();
  const auto start = timed ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
  try {
    f();
  } catch (const std::exception& ex) {
    errors_.fetch_add(1);
    if (on_error) on_error(ex.what());
  } catch (...) {
    errors_.fetch_add(1);
    if (on_error) on_error("unknown exception");
  }
  if (timed) note_run(std::chrono::steady_clock::now() - start);
}

void CallbackGroup::wake_publishers() const {
  for (const auto& s : *subscriptions()) s->wake_publishers();
}

std::size_t CallbackGroup::run_claimed(std::size_t max, const SubList& subs, bool after_stop) {
  std::size_t ran = 0;
  // A stopping executor ends the batch: its callbacks may wait on queues that
  // the workers already gone will never drain.
  while (ran < max && !dead() && (after_stop || !executor_stopping())) {
    // The oldest stamp goes first: arrival order across the group's queues.
    SubscriptionBase* best = nullptr;
    std::uint64_t best_stamp = 0;
    for (const auto& s : subs) {
      if (const auto st = s->front_stamp(); st && (best == nullptr || *st < best_stamp)) {
        best = s.get();
        best_stamp = *st;
      }
    }
    if (ticks_size_.load(std::memory_order_acquire) != 0) {
      std::shared_ptr<Timer> timer;
      {
        std::lock_guard lk(mu_);
        if (!ticks_.empty() && (best == nullptr || ticks_.front().stamp < best_stamp)) {
          timer = std::move(ticks_.front().timer);
          ticks_.pop_front();
          ticks_size_.fetch_sub(1, std::memory_order_relaxed);
        }
      }
      if (timer) {
        if (!timer->cancelled()) {
          timer->fired_.fetch_add(1, std::memory_order_relaxed);
          guarded([&] { timer->cb_(); });
          ++ran;
        }
        continue;
      }
    }
    if (best == nullptr) break;
    QueuedMessage m;
    if (!best->pop(&m)) continue;  // a keep-last publisher dropped it meanwhile: choose again
    best->made_room();
    if (best->cancelled_.load(std::memory_order_acquire)) continue;
    guarded([&] { best->dispatch(std::move(m.msg), m.info); });
    ++ran;
  }
  return ran;
}

void CallbackGroup::attach(std::shared_ptr<detail::ExecutorCore> core, bool unbounded_reliable) {
  {
    std::lock_guard lk(mu_);
    if (core_ && core_ != core) throw std::logic_error("node '" + owner_ + "' is already in an executor");
    core_ = core;
    if (std::find(cores_seen_.begin(), cores_seen_.end(), core) == cores_seen_.end()) cores_seen_.push_back(core);
    unbounded_reliable_.store(unbounded_reliable);
    core_raw_.store(core.get(), std::memory_order_release);
  }
  {
    std::lock_guard lk(core->mu);
    if (std::find(core->groups.begin(), core->groups.end(), shared_from_this()) == core->groups.end()) {
      core->groups.push_back(shared_from_this());
      core->groups_version.fetch_add(1);
    }
  }
  if (core->fifo) {
    if (has_work() && !dead() && !scheduled_.exchange(true)) {
      std::lock_guard lk(core->mu);
      core->ready.push_back(shared_from_this());
    }
  } else {
    core->wake_all();
  }
}

void CallbackGroup::detach() {
  std::shared_ptr<detail::ExecutorCore> core;
  {
    std::lock_guard lk(mu_);
    core.swap(core_);
    core_raw_.store(nullptr, std::memory_order_release);
  }
  if (!core) return;
  std::lock_guard lk(core->mu);
  std::erase(core->groups, shared_from_this());
  std::erase(core->ready, shared_from_this());
  scheduled_.store(false);
  core->groups_version.fetch_add(1);
}

void CallbackGroup::shutdown() {
  std::shared_ptr<const SubList> subs;
  {
    std::unique_lock lk(mu_);
    dead_.store(true, std::memory_order_seq_cst);
    ticks_.clear();
    ticks_size_.store(0);
    if (running_thread_.load() != std::this_thread::get_id()) {
      shutdown_waiting_.store(true, std::memory_order_seq_cst);
      idle_.wait(lk, [&] { return !running_.load(std::memory_order_seq_cst); });
    }
    // Listing a subscription keeps it alive; it keeps this group alive.
    subs = std::exchange(subs_, std::make_shared<SubList>());
    subs_version_.fetch_add(1, std::memory_order_release);
  }
  for (const auto& s : *subs) s->clear();  // queued messages go now, not with the last handle
  subs.reset();
  detach();
}

Executor* CallbackGroup::executor() const {
  std::shared_ptr<detail::ExecutorCore> core;
  {
    std::lock_guard lk(mu_);
    core = core_;
  }
  if (!core) return nullptr;
  std::lock_guard lk(core->mu);
  return core->owner;
}
}  // namespace tinyline::bus
