// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/executor.hpp>

#include <algorithm>

#include <tinyline/bus/node.hpp>

#include "executor_internal.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define TL_CPU_RELAX() _mm_pause()
#else
#define TL_CPU_RELAX() ((void)0)
#endif

namespace tinyline::bus {

namespace detail {
thread_local constinit const ExecutorCore* tl_core = nullptr;
}  // namespace detail

using detail::CoreScope;
using detail::tl_core;

namespace {

struct WorkerCount {
  explicit WorkerCount(detail::ExecutorCore& c) : core(c) { core.workers.fetch_add(1, std::memory_order_seq_cst); }
  ~WorkerCount() { core.workers.fetch_sub(1, std::memory_order_seq_cst); }
  detail::ExecutorCore& core;
};
}  // namespace

Executor* current_executor() { return tl_core ? tl_core->owner : nullptr; }

Executor::Executor(Clock& clock, ExecutorOptions options)
    : clock_(clock), options_(options), core_(std::make_shared<detail::ExecutorCore>()) {
  if (options_.threads < 1) throw std::invalid_argument("an executor needs at least one thread");
  core_->threads = options_.threads;
  core_->owner = this;
  // Sim-time changes may make timers due: wake sleeping workers.
  clock_listener_ = clock_.add_listener([c = core_] { c->wake_all(); });
}

Executor::~Executor() {
  stop();
  clock_.remove_listener(clock_listener_);
  std::vector<std::shared_ptr<Node>> nodes;
  {
    std::lock_guard lk(nodes_mu_);
    nodes.swap(nodes_);
  }
  for (auto& n : nodes) n->callback_group()->detach();
  std::lock_guard lk(core_->mu);
  core_->owner = nullptr;
  core_->groups.clear();
  core_->ready.clear();
}

void Executor::add_node(const std::shared_ptr<Node>& node) {
  if (&node->clock() != &clock_) {
    throw std::invalid_argument("node '" + node->full_name() + "' belongs to another context than this executor");
  }
  {
    std::lock_guard lk(nodes_mu_);
    nodes_.push_back(node);
    unstarted_.push_back(node);
  }
  node->callback_group()->attach(core_, unbounded_);
  for (const auto& t : node->timers()) add_timer(t, node->callback_group());
}

void Executor::remove_node(const std::shared_ptr<Node>& node) {
  {
    std::lock_guard lk(nodes_mu_);
    std::erase(nodes_, node);
    std::erase(unstarted_, node);
  }
  node->callback_group()->detach();
  std::lock_guard lk(timers_mu_);
  std::erase_if(timers_, [&](const auto& p) { return p.second == node->callback_group(); });
}

void Executor::add_timer(const std::shared_ptr<Timer>& t, const std::shared_ptr<CallbackGroup>& g) {
  {
    std::lock_guard lk(timers_mu_);
    for (const auto& p : timers_)
      if (p.first == t) return;
    if (clock_.started() && !t->anchored_) {  // created while time runs: count from now
      t->next_due_ = clock_.now() + t->period_;
      t->anchored_ = true;
    }
    timers_.emplace_back(t, g);
  }
  core_->wake_all();
}

void Executor::start_pending_nodes() {
  std::vector<std::shared_ptr<Node>> todo;
  {
    std::lock_guard lk(nodes_mu_);
    todo.swap(unstarted_);
  }
  // Every node checks its inputs before any starts: a bad calibration must
  // not leave a recorder that already began.
  for (auto& n : todo) {
    try {
      n->on_configure();
    } catch (const std::exception& e) {
      throw std::runtime_error("node '" + n->full_name() + "' failed to configure: " + e.what());
    }
  }
  for (auto& n : todo) {
    try {
      n->on_start();
    } catch (const std::exception& e) {
      throw std::runtime_error("node '" + n->full_name() + "' failed to start: " + e.what());
    }
    // on_start may have created timers.
    for (const auto& t : n->timers()) add_timer(t, n->callback_group());
  }
}

void Executor::stop() {
  stop_.store(true);
  if (core_->fifo) {
    core_->wake_all();
    return;
  }
  core_->stopping.store(true, std::memory_order_seq_cst);
  core_->wake_all();
  std::vector<std::shared_ptr<CallbackGroup>> groups;
  {
    std::lock_guard lk(core_->mu);
    groups = core_->groups;
  }
  for (const auto& g : groups) g->wake_publishers();
}

std::optional<Time> Executor::fire_due_timers(Time now, bool catch_up) {
  std::vector<std::pair<std::shared_ptr<Timer>, std::shared_ptr<CallbackGroup>>> due;
  std::optional<Time> next;
  {
    std::lock_guard lk(timers_mu_);
    std::erase_if(timers_, [](const auto& p) { return p.first->cancelled(); });
    if (!clock_.started()) return std::nullopt;
    for (auto& [t, g] : timers_) {
      if (!t->anchored_) {  // created before time started: count from its start
        t->next_due_ = (clock_.is_sim() ? clock_.start_time() : now) + t->period_;
        t->anchored_ = true;
      } else if (now < t->next_due_ - t->period_) {  // time went back (a replay loop): re-anchor
        t->next_due_ = now + t->period_;
      }
      while (t->next_due_ <= now) {
        due.emplace_back(t, g);
        t->next_due_ += t->period_;
        if (!catch_up && t->next_due_ <= now) t->next_due_ = now + t->period_;  // skip missed periods
      }
      if (!next || t->next_due_ < *next) next = t->next_due_;
    }
  }
  for (auto& [t, g] : due) g->notify(t);
  return next;
}

void Executor::refresh(View& v) {
  const std::uint64_t gv = core_->groups_version.load(std::memory_order_acquire);
  if (gv != v.version) {
    std::vector<std::shared_ptr<CallbackGroup>> groups;
    {
      std::lock_guard lk(core_->mu);
      groups = core_->groups;
      v.version = core_->groups_version.load();
    }
    std::vector<View::Group> next;
    for (auto& g : groups) {
      View::Group e;
      for (auto& old : v.groups)
        if (old.g == g) e = std::move(old);
      e.g = std::move(g);
      next.push_back(std::move(e));
    }
    v.groups = std::move(next);
  }
  for (auto& e : v.groups) {
    if (e.g->subscriptions_version() != e.version) e.subs = e.g->subscriptions(&e.version);
  }
}

bool Executor::any_pending(View& v) {
  if (core_->groups_version.load(std::memory_order_relaxed) != v.version) return true;
  for (const auto& e : v.groups) {
    if (e.g->subscriptions_version() != e.version) return true;
    if (e.g->has_work(*e.subs)) return true;
  }
  return false;
}

bool Executor::run_some_group(View& v) {
  refresh(v);
  const std::size_t n = v.groups.size();
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = (v.cursor + k) % n;
    const View::Group& e = v.groups[i];
    if (!e.g->has_work(*e.subs)) continue;
    if (e.g->try_run(options_.batch, nullptr, e.subs.get())) {
      v.cursor = (i + 1) % n;  // round robin: the next scan starts after it
      return true;
    }
  }
  return false;
}

bool Executor::poll_for_work(View& view, Duration how_long) {
  // One poller at a time. After its first polls it yields the core between
  // polls: with more busy threads than cores, a pure spin keeps off the
  // processor the very thread bringing the next message (a DDS receive
  // thread, a publisher). While yielded it is no poller (publishers then wake
  // a sleeping worker), and a yield that took long means the core is busy
  // with other work: it stops polling and sleeps rather than wait for the
  // scheduler's next turn. The clock is read once per 8 pauses.
  constexpr unsigned kPausePolls = 64;
  constexpr auto kBusyCore = std::chrono::microseconds(50);
  int none = 0;
  if (!core_->spinning.compare_exchange_strong(none, 1, std::memory_order_seq_cst)) return false;
  bool polling = true;
  bool found = false;
  const auto end = std::chrono::steady_clock::now() + how_long;
  for (unsigned polls = 0; !stop_.load(std::memory_order_relaxed); ++polls) {
    if (any_pending(view)) {
      found = true;
      break;
    }
    if (polls < kPausePolls) {
      TL_CPU_RELAX();
      if ((polls & 7u) == 7u && std::chrono::steady_clock::now() >= end) break;
      continue;
    }
    core_->spinning.store(0, std::memory_order_seq_cst);
    polling = false;
    const auto before = std::chrono::steady_clock::now();
    std::this_thread::yield();
    const auto after = std::chrono::steady_clock::now();
    if (after - before > kBusyCore || after >= end) break;
    none = 0;
    if (!core_->spinning.compare_exchange_strong(none, 1, std::memory_order_seq_cst)) break;  // another one polls
    polling = true;
  }
  if (polling) core_->spinning.store(0, std::memory_order_seq_cst);
  return found;
}

void Executor::worker_loop() {
  constexpr Duration kIdleWait = std::chrono::milliseconds(100);
  CoreScope scope(core_.get());
  WorkerCount counted(*core_);
  View view;
  while (!stop_.load()) {
    const Time now = clock_.now();
    const auto next = fire_due_timers(now, clock_.is_sim());
    if (run_some_group(view)) continue;
    Duration wait = kIdleWait;
    if (next && !clock_.is_sim()) wait = std::clamp<Duration>(*next - now, Duration::zero(), kIdleWait);
    if (wait.count() == 0) continue;
    // Poll briefly before sleeping: a message from another thread then costs a
    // few cache-line transfers instead of a futex wake-up.
    const bool found = poll_for_work(view, std::min(options_.spin, wait));
    // A message found while polling runs at once; timers are looked at on
    // the next turn (one message's callback later at most).
    if (found) {
      run_some_group(view);
      continue;
    }
    // Sleep. Announce it first, then look once more: a publisher queues a
    // message and then reads `sleepers`, so one of the two sees the other.
    std::unique_lock lk(core_->mu);
    core_->sleepers.fetch_add(1, std::memory_order_seq_cst);
    core_->cv.wait_for(lk, wait, [&] { return stop_.load() || any_pending(view); });
    core_->sleepers.fetch_sub(1, std::memory_order_seq_cst);
  }
}

Executor::SpinGuard::SpinGuard(Executor& e) : e_(e) {
  if (e_.spinning_.exchange(true, std::memory_order_acq_rel)) {
    throw std::logic_error(
        "this executor is already spinning (spin() or spin_some() on another thread, or inside "
        "one of its callbacks)");
  }
}

Executor::SpinGuard::~SpinGuard() { e_.spinning_.store(false, std::memory_order_release); }

void Executor::spin() {
  const SpinGuard guard(*this);
  // A stop() that comes before spin() gets going ends this spin at once (a
  // thread started to spin may begin after its owner already asked it to
  // stop); the request is consumed on the way out, so a later spin() runs.
  core_->stopping.store(false, std::memory_order_seq_cst);
  start_pending_nodes();
  worker_loop();
  stop_.store(false);
}

std::size_t Executor::spin_some() {
  const SpinGuard guard(*this);
  core_->stopping.store(false, std::memory_order_seq_cst);
  start_pending_nodes();
  fire_due_timers(clock_.now(), clock_.is_sim());
  CoreScope scope(core_.get());
  View view;
  std::size_t n = 0;
  while (run_some_group(view)) ++n;
  return n;
}
}  // namespace tinyline::bus
