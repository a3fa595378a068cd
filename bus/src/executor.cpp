// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/executor.hpp>

#include <algorithm>

#include <fmt/format.h>

#include <tinyline/bus/graph.hpp>
#include <tinyline/bus/node.hpp>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define TL_CPU_RELAX() _mm_pause()
#else
#define TL_CPU_RELAX() ((void)0)
#endif

namespace tinyline::bus {

namespace {
thread_local const detail::ExecutorCore* tl_core = nullptr;

struct CoreScope {
  explicit CoreScope(const detail::ExecutorCore* c) : prev(tl_core) { tl_core = c; }
  ~CoreScope() { tl_core = prev; }
  const detail::ExecutorCore* prev;
};

thread_local InlineDelivery* tl_inline = nullptr;
// Set while this thread runs callbacks inline. A callback's publish may come
// back to this thread inline again (Cyclone delivers to readers of its own
// process on the writer's thread): that one goes to the workers, so two
// graphs replying to each other cannot recurse without end.
thread_local bool tl_running_inline = false;

// Inline runs hold up the transport thread that makes them (DDS's receive
// thread also handles acknowledgements for every topic): callbacks that take
// longer than this, several times in a row, go back to the workers for a
// while. The runs of a message or two on the way through a graph take a few
// microseconds; large messages take longer but are copy-bound anyway.
constexpr auto kInlineBudget = std::chrono::microseconds(200);
constexpr int kSlowInlineRuns = 3;
constexpr auto kInlinePause = std::chrono::seconds(1);
// One inline run this long is no lost core: the callbacks block (a full pipe,
// a lock, a disk). They run on workers for good, where blocking holds up only
// their own node.
constexpr auto kInlineStall = std::chrono::milliseconds(20);
constexpr std::size_t kInlineBatch = 8;
// Callbacks a waiting reliable publisher runs for the full subscriber per
// turn: enough to make room, few enough to go back to its own message soon.
constexpr std::size_t kHelpBatch = 16;

std::int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

struct WorkerCount {
  explicit WorkerCount(detail::ExecutorCore& c) : core(c) { core.workers.fetch_add(1, std::memory_order_seq_cst); }
  ~WorkerCount() { core.workers.fetch_sub(1, std::memory_order_seq_cst); }
  detail::ExecutorCore& core;
};
}  // namespace

Executor* current_executor() { return tl_core ? tl_core->owner : nullptr; }

// ---------------------------------------------------------------------------- CallbackGroup

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

bool CallbackGroup::accepts_inline() const {
  if (inline_refused_.load(std::memory_order_relaxed)) return false;
  const std::int64_t until = inline_paused_until_ns_.load(std::memory_order_relaxed);
  return until == 0 || steady_ns() >= until;
}

bool CallbackGroup::try_run_inline() {
  detail::ExecutorCore* core = core_raw_.load(std::memory_order_acquire);
  if (core == nullptr || core->fifo || core->workers.load(std::memory_order_seq_cst) == 0 ||
      core->stopping.load(std::memory_order_seq_cst) || dead() || !accepts_inline()) {
    return false;
  }
  if (tl_running_inline) return false;
  CoreScope scope(core);  // current_executor() inside the callbacks, as on a worker
  const auto start = std::chrono::steady_clock::now();
  tl_running_inline = true;
  inline_since_ns_.store(steady_ns(), std::memory_order_relaxed);
  const bool ran = try_run(kInlineBatch);
  inline_since_ns_.store(0, std::memory_order_relaxed);
  tl_running_inline = false;
  if (!ran) return false;
  note_inline_run(std::chrono::steady_clock::now() - start);
  // Work that came meanwhile (or beyond the batch) announced itself to a
  // group that was running; make sure a worker looks.
  if (has_work()) core->wake();
  return true;
}

std::chrono::nanoseconds CallbackGroup::inline_run_time() const {
  const std::int64_t since = inline_since_ns_.load(std::memory_order_relaxed);
  return std::chrono::nanoseconds(since == 0 ? 0 : std::max<std::int64_t>(0, steady_ns() - since));
}

void CallbackGroup::note_inline_run(std::chrono::steady_clock::duration took) {
  if (took >= kInlineStall) {
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

template <class F>
void CallbackGroup::guarded(F&& f) {
  try {
    f();
  } catch (const std::exception& ex) {
    errors_.fetch_add(1);
    if (on_error) on_error(ex.what());
  } catch (...) {
    errors_.fetch_add(1);
    if (on_error) on_error("unknown exception");
  }
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

// ---------------------------------------------------------------------------- Executor

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

void Executor::spin() {
  // A stop() that comes before spin() gets going ends this spin at once (a
  // thread started to spin may begin after its owner already asked it to
  // stop); the request is consumed on the way out, so a later spin() runs.
  core_->stopping.store(false, std::memory_order_seq_cst);
  start_pending_nodes();
  worker_loop();
  stop_.store(false);
}

std::size_t Executor::spin_some() {
  core_->stopping.store(false, std::memory_order_seq_cst);
  start_pending_nodes();
  fire_due_timers(clock_.now(), clock_.is_sim());
  CoreScope scope(core_.get());
  View view;
  std::size_t n = 0;
  while (run_some_group(view)) ++n;
  return n;
}

void MultiThreadedExecutor::spin() {
  core_->stopping.store(false, std::memory_order_seq_cst);  // see Executor::spin()
  start_pending_nodes();
  std::vector<std::thread> workers;
  for (int i = 1; i < options_.threads; ++i) workers.emplace_back([this] { worker_loop(); });
  worker_loop();
  for (auto& w : workers) w.join();
  stop_.store(false);  // see Executor::spin()
}

// ---------------------------------------------------------------------------- InlineDelivery

InlineDelivery::InlineDelivery() : previous_(tl_inline) { tl_inline = this; }

InlineDelivery::~InlineDelivery() {
  flush();
  tl_inline = previous_;
}

bool InlineDelivery::defer(CallbackGroup& g) {
  InlineDelivery* d = tl_inline;
  if (d == nullptr) return false;
  for (const auto& p : d->pending_)
    if (p.get() == &g) return true;
  d->pending_.push_back(g.shared_from_this());
  return true;
}

void InlineDelivery::flush() {
  if (pending_.empty()) return;
  std::vector<std::shared_ptr<CallbackGroup>> todo;
  todo.swap(pending_);
  // The callbacks' own publishes wake workers: one level of inline runs.
  tl_inline = previous_;
  for (const auto& g : todo) {
    if (!g->try_run_inline()) g->announce();
  }
  tl_inline = this;
  todo.clear();
  if (pending_.capacity() == 0) pending_.swap(todo);  // keep the allocation
}

// ---------------------------------------------------------------------------- DeterministicExecutor

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
