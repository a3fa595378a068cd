// SPDX-License-Identifier: Apache-2.0
// Executors run callbacks. The rule that makes node code lock-free: the
// callbacks of one node (its callback group) never run concurrently, whatever
// the executor; different nodes may run on different threads.
//
//  SingleThreadedExecutor    one thread runs everything.
//  MultiThreadedExecutor     N threads; a node's callbacks stay serial.
//  DeterministicExecutor     no threads: the caller steps it. Each message and
//                            every callback it triggers runs before the next
//                            one; timers fire on sim time in order. For replay
//                            tests: same input, same output, every run.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <tinyline/bus/clock.hpp>
#include <tinyline/bus/message_info.hpp>
#include <tinyline/bus/time.hpp>

namespace tinyline::bus {

class Executor;
class Node;
class SubscriptionBase;
class CallbackGroup;
class InlineDelivery;

namespace detail {
/// What an executor shares with the groups attached to it (a separate object,
/// so a publisher racing an executor's destruction never touches freed memory:
/// a group keeps every core it was attached to alive).
///
/// Real-time executors: workers poll their groups' subscription queues; a
/// publisher only wakes a sleeping worker. Delivering a message then moves
/// one queue slot between cores, no lock and no hand-off.
/// Deterministic executors: groups with work wait in a FIFO, in arrival order.
struct ExecutorCore {
  std::mutex mu;
  std::condition_variable cv;
  bool fifo = false;
  std::deque<std::shared_ptr<CallbackGroup>> ready;  ///< fifo mode only
  int threads = 1;
  Executor* owner = nullptr;                           ///< nulled when the executor goes away (under mu)
  std::vector<std::shared_ptr<CallbackGroup>> groups;  ///< attached (under mu)
  std::atomic<std::uint64_t> groups_version{0};
  // Read by every publish, written only when a worker sleeps: its own line.
  alignas(64) std::atomic<int> sleepers{0};  ///< workers asleep on cv
  /// 1 while a worker polls for work before sleeping: one poller is enough to
  /// spare publishers the wake-up, and more would take cores from them.
  std::atomic<int> spinning{0};
  /// Set by stop() (threaded executors) until the next spin: no worker will
  /// take more messages, so groups end their batch and reliable publishers
  /// stop waiting for room in these queues.
  std::atomic<bool> stopping{false};
  /// Worker threads inside spin() now: callbacks run inline (InlineDelivery)
  /// only while the executor itself runs, never before it starts.
  std::atomic<int> workers{0};

  /// Publisher side, after queueing work: wake one sleeping worker if any,
  /// unless one is polling (it stops polling, then looks once more before
  /// it sleeps: with seq_cst on both sides one of the two sees the other).
  void wake() {
    if (spinning.load(std::memory_order_seq_cst) == 0 && sleepers.load(std::memory_order_seq_cst) > 0) {
      // Taking the lock orders us after a worker between its last look and
      // its wait; notifying after releasing it spares the woken worker from
      // blocking on the lock we still hold (a second futex round trip).
      { std::lock_guard lk(mu); }
      cv.notify_one();
    }
  }
  void wake_all() {
    std::lock_guard lk(mu);
    cv.notify_all();
  }
};
}  // namespace detail

/// A periodic callback on the context clock (wall or sim).
class Timer {
 public:
  Timer(Duration period, std::function<void()> cb) : period_(period), cb_(std::move(cb)) {
    if (period_.count() <= 0) throw std::invalid_argument("timer period must be positive");
  }
  Duration period() const { return period_; }
  std::uint64_t fired() const { return fired_.load(std::memory_order_relaxed); }
  void cancel() { cancelled_.store(true); }
  bool cancelled() const { return cancelled_.load(); }

 private:
  friend class Executor;
  friend class DeterministicExecutor;
  friend class CallbackGroup;
  Duration period_;
  std::function<void()> cb_;
  std::atomic<bool> cancelled_{false};
  std::atomic<std::uint64_t> fired_{0};
  // Owned by the executor (under its mutex):
  bool anchored_ = false;
  Time next_due_;
};

/// The unit of mutual exclusion: one per node. Messages wait in the queues of
/// its subscriptions (lock-free rings); every message and timer tick gets a
/// stamp from the group, and the group runs them in stamp order.
class CallbackGroup : public std::enable_shared_from_this<CallbackGroup> {
 public:
  using SubList = std::vector<std::shared_ptr<SubscriptionBase>>;

  explicit CallbackGroup(std::string owner) : owner_(std::move(owner)) {}

  const std::string& owner() const { return owner_; }

  /// Queues a timer tick (subscriptions queue through SubscriptionBase::enqueue).
  void notify(const std::shared_ptr<Timer>& timer);

  /// The subscriptions whose queues this group drains. Listing one keeps it
  /// alive until cancel() or shutdown() takes it off.
  void add_subscription(const std::shared_ptr<SubscriptionBase>& s);
  void remove_subscription(const SubscriptionBase* s);
  /// The current list and its version (the version changes with the list).
  std::shared_ptr<const SubList> subscriptions(std::uint64_t* version = nullptr) const;
  std::uint64_t subscriptions_version() const { return subs_version_.load(std::memory_order_acquire); }

  /// Claims the group and runs up to `max` pending callbacks. Returns false if
  /// another thread is running it; `ran` gets the number run. `subs` is the
  /// caller's copy of subscriptions() (fetched here when null).
  bool try_run(std::size_t max, std::size_t* ran = nullptr, const SubList* subs = nullptr);
  /// As try_run, also after the executor was asked to stop: a node finishing
  /// in on_stop() runs what its queues still hold (a recorder records it).
  /// Only for callbacks that never wait on another node's queue.
  bool try_run_after_stop(std::size_t max, std::size_t* ran = nullptr);
  /// True when a message or a tick waits (`subs` as for try_run).
  bool has_work(const SubList& subs) const;
  bool has_work() const { return has_work(*subscriptions()); }

  void attach(std::shared_ptr<detail::ExecutorCore> core, bool unbounded_reliable);
  void detach();
  /// Stops all future callbacks and waits for a running one to finish.
  void shutdown();
  bool dead() const { return dead_.load(std::memory_order_acquire); }

  /// The executor this group is attached to (nullptr if none).
  Executor* executor() const;
  bool unbounded_reliable() const { return unbounded_reliable_.load(); }
  /// True when the executor this group is attached to was asked to stop.
  bool executor_stopping() const {
    const detail::ExecutorCore* core = core_raw_.load(std::memory_order_acquire);
    return core != nullptr && core->stopping.load(std::memory_order_seq_cst);
  }
  /// Wakes publishers waiting for room in this group's reliable queues (they
  /// look again at why they wait: the executor may have stopped).
  void wake_publishers() const;
  /// A reliable publisher that finds this group's queue full runs the
  /// group's callbacks itself when it is one of the group's executor threads
  /// and the group is idle: the node that can make room runs, instead of
  /// waiting for a worker that every blocked publisher may be holding.
  /// Returns true if it ran at least one callback.
  bool run_for_waiting_publisher();
  /// True when the calling thread is inside one of this group's callbacks.
  bool running_here() const {
    return running_.load(std::memory_order_acquire) && running_thread_.load() == std::this_thread::get_id();
  }

  /// Runs this group's queued callbacks on the calling thread (an
  /// InlineRunner's, see InlineDelivery) if may_run_inline() and the group is
  /// idle; false otherwise (the caller then announces the work to a worker).
  /// A run that slept long leaves inline runs for good (note_inline_run).
  bool try_run_inline();
  /// True when an inline run would be tried now: executor workers running
  /// and not stopping, group alive, and accepts_inline().
  bool may_run_inline() const;
  /// From now on this group's callbacks run only on its executor's threads:
  /// they may wait (a node with a reliable publisher waits for room), and a
  /// transport's delivery thread must not.
  void refuse_inline() { inline_refused_.store(true, std::memory_order_relaxed); }
  /// True when the group may run inline now: not refused nor paused, and
  /// proven: its last callbacks ran short (a callback that blocks on its
  /// first run then blocks a worker, never a transport's delivery thread).
  bool accepts_inline() const;
  /// True once the group's last callbacks (a few in a row) each ran within
  /// the inline budget, wherever they ran.
  bool proven() const;
  /// How long the inline run in progress has lasted (zero when none runs):
  /// a transport watches it, since its delivery thread waits for the run.
  std::chrono::nanoseconds inline_run_time() const;
  /// Inline runs stop for good: the node's callbacks once held a transport's
  /// delivery thread too long (they may block) and run on workers from now on.
  void stop_inline() { inline_refused_.store(true, std::memory_order_relaxed); }

  /// Callback exceptions caught (and logged) so far.
  std::uint64_t errors() const { return errors_.load(); }
  std::function<void(const std::string&)> on_error;  ///< set by the node: logs the failure

 private:
  friend class SubscriptionBase;
  friend class DeterministicExecutor;
  friend class InlineDelivery;
  friend class InlineRunner;
  struct Tick {
    std::uint64_t stamp = 0;
    std::shared_ptr<Timer> timer;
  };
  /// Publisher side: the arrival stamp of a new message or tick.
  std::uint64_t next_stamp() { return next_stamp_.fetch_add(1, std::memory_order_relaxed); }
  /// Publisher side, after queueing: wakes a worker or enters the FIFO.
  void announce();
  bool claim_and_run(std::size_t max, std::size_t* ran, const SubList* subs, bool after_stop);
  std::size_t run_claimed(std::size_t max, const SubList& subs, bool after_stop);
  /// Books one inline run's wall time and whether the thread waited in it
  /// (went to sleep: a lock, a pipe, a disk): a run that waited long leaves
  /// inline runs for good; one that was only long (lost its core) counts as
  /// slow, and slow runs in a row pause inline runs a while.
  void note_inline_run(std::chrono::steady_clock::duration took, bool waited);
  /// Books one callback's wall time towards the proof inline runs need.
  void note_run(std::chrono::steady_clock::duration took);
  /// Runs a callback, catching and counting what it throws; times it while
  /// the group is not proven yet.
  template <class F>
  void guarded(F&& f);

  // Read-mostly.
  const std::string owner_;
  std::atomic<detail::ExecutorCore*> core_raw_{nullptr};  ///< the attached core (lock-free read)
  std::atomic<bool> dead_{false};
  std::atomic<std::uint64_t> subs_version_{0};
  std::atomic<std::size_t> ticks_size_{0};
  std::atomic<bool> unbounded_reliable_{false};
  // Under mu_.
  mutable std::mutex mu_;
  std::condition_variable idle_;
  std::shared_ptr<const SubList> subs_ = std::make_shared<SubList>();
  std::deque<Tick> ticks_;
  std::shared_ptr<detail::ExecutorCore> core_;
  std::vector<std::shared_ptr<detail::ExecutorCore>> cores_seen_;  // keeps core_raw_ valid for racing publishers
  // Publishers write it on every message.
  alignas(64) std::atomic<std::uint64_t> next_stamp_{0};
  // The running worker writes these.
  alignas(64) std::atomic<bool> running_{false};
  std::atomic<std::thread::id> running_thread_{};
  std::atomic<bool> shutdown_waiting_{false};
  std::atomic<std::uint64_t> errors_{0};
  // Inline runs (InlineDelivery).
  std::atomic<bool> inline_refused_{false};
  std::atomic<int> short_runs_{0};                       ///< callbacks in a row within the budget (capped)
  std::atomic<int> slow_inline_runs_{0};                 ///< in a row over the budget
  std::atomic<std::int64_t> inline_paused_until_ns_{0};  ///< steady clock; 0: not paused
  std::atomic<std::int64_t> inline_since_ns_{0};         ///< steady clock; 0: no inline run now
  // Deterministic executors: in the FIFO already.
  alignas(64) std::atomic<bool> scheduled_{false};
};

struct ExecutorOptions {
  int threads = 1;
  /// Before sleeping, an idle worker polls this long for new work (one worker
  /// at a time, yielding the core between polls): cross-thread delivery then
  /// costs a cache miss instead of a futex wake-up.
  Duration spin = std::chrono::microseconds(50);
  /// Callbacks a worker runs from one group before moving on (fairness).
  std::size_t batch = 64;
};

class Executor {
 public:
  explicit Executor(Clock& clock, ExecutorOptions options = {});
  virtual ~Executor();
  Executor(const Executor&) = delete;
  Executor& operator=(const Executor&) = delete;

  void add_node(const std::shared_ptr<Node>& node);
  void remove_node(const std::shared_ptr<Node>& node);

  /// Blocks running callbacks until stop() (from any thread or a signal-safe
  /// flag). A stop() made before spin() starts ends that spin at once.
  /// Throws std::logic_error while the executor already spins (spin() or
  /// spin_some() on another thread, or inside one of its callbacks).
  virtual void spin();
  /// Runs what is ready now (and due timers), then returns. Throws as spin().
  std::size_t spin_some();
  void stop();
  bool stopped() const { return stop_.load(); }

  int threads() const { return options_.threads; }
  Clock& clock() { return clock_; }

  // Called by nodes.
  void add_timer(const std::shared_ptr<Timer>& t, const std::shared_ptr<CallbackGroup>& g);

 protected:
  /// Marks the executor spinning for its lifetime; throws std::logic_error
  /// when it already spins: two spins would run every node twice over.
  class SpinGuard {
   public:
    explicit SpinGuard(Executor& e);
    ~SpinGuard();
    SpinGuard(const SpinGuard&) = delete;
    SpinGuard& operator=(const SpinGuard&) = delete;

   private:
    Executor& e_;
  };
  /// Calls on_configure() of every node added since the last call, then their on_start().
  void start_pending_nodes();
  /// A worker's copies of the attached groups and their subscription lists
  /// (refreshed when a version changes), so polling takes no lock.
  struct View {
    struct Group {
      std::shared_ptr<CallbackGroup> g;
      std::shared_ptr<const CallbackGroup::SubList> subs;
      std::uint64_t version = ~std::uint64_t{0};
    };
    std::vector<Group> groups;
    std::uint64_t version = ~std::uint64_t{0};
    std::size_t cursor = 0;
  };
  /// Brings `v` up to date with the attached groups and their subscriptions.
  void refresh(View& v);
  /// True when some group of `v` has work (or the group list changed).
  bool any_pending(View& v);
  /// Runs one batch of some group with work; false if none had any.
  bool run_some_group(View& v);
  /// Hands due timers to their groups; returns the next due time if any.
  std::optional<Time> fire_due_timers(Time now, bool catch_up);
  /// Polls up to `how_long` for work (ExecutorOptions::spin); true if some came.
  bool poll_for_work(View& view, Duration how_long);
  /// The worker loop of spin().
  void worker_loop();

  Clock& clock_;
  ExecutorOptions options_;
  bool unbounded_ = false;
  std::shared_ptr<detail::ExecutorCore> core_;
  std::mutex timers_mu_;
  std::vector<std::pair<std::shared_ptr<Timer>, std::shared_ptr<CallbackGroup>>> timers_;
  std::mutex nodes_mu_;
  std::vector<std::shared_ptr<Node>> nodes_;
  std::vector<std::shared_ptr<Node>> unstarted_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> spinning_{false};  ///< see SpinGuard
  int clock_listener_ = 0;
};

class SingleThreadedExecutor : public Executor {
 public:
  explicit SingleThreadedExecutor(Clock& clock, Duration spin = std::chrono::microseconds(50))
      : Executor(clock, ExecutorOptions{1, spin, 64}) {}
};

class MultiThreadedExecutor : public Executor {
 public:
  MultiThreadedExecutor(Clock& clock, int threads, Duration spin = std::chrono::microseconds(50))
      : Executor(clock, ExecutorOptions{threads, spin, 64}) {}
  void spin() override;
};

class DeterministicExecutor : public Executor {
 public:
  /// The clock must be a sim clock: this executor owns its time.
  explicit DeterministicExecutor(Clock& clock);

  /// Runs every ready callback, and everything they trigger, until nothing is
  /// left. Returns the number of callbacks run.
  std::size_t spin_until_idle();

  /// Moves sim time to `t`: every timer due on the way fires at its own due
  /// time (now() inside it equals that time), in time order, each followed by
  /// spin_until_idle().
  void advance_to(Time t);

  void spin() override;  // same as spin_until_idle()
};

/// The executor currently running a callback on this thread, if any.
Executor* current_executor();

struct InlineRunnerOptions {
  /// How long one inline run may hold the runner before a fresh thread
  /// takes over (checked every `bound`: at most twice this in all).
  std::chrono::nanoseconds bound = std::chrono::milliseconds(20);
  /// An idle runner polls this long for work before it sleeps: a message
  /// that comes meanwhile costs a cache miss, not a futex wake-up.
  std::chrono::nanoseconds spin = std::chrono::microseconds(50);
};

/// The thread on which a transport's delivered messages run their
/// subscribers' callbacks inline (see InlineDelivery), owned by the bus so
/// that no callback ever holds the transport's own thread (DDS's receive
/// thread, which every subscriber of the process waits on). A watchdog looks
/// at the run in progress every `bound`: a run older than that keeps its
/// thread, and a fresh thread takes over everything queued behind it, so a
/// callback that blocks for good holds up its own node and nobody else. The
/// old thread ends once its run returns; the run books itself there as every
/// inline run does (CallbackGroup::note_inline_run: one that slept leaves
/// inline runs for good).
class InlineRunner {
 public:
  using Options = InlineRunnerOptions;
  /// Told when a run outlived the bound: the tag given with the work (a
  /// transport's topic, say), the node, and how long it had run. Called on
  /// the watchdog's thread.
  using OnStall = std::function<void(const void* tag, const std::string& node, std::chrono::nanoseconds held)>;

  explicit InlineRunner(OnStall on_stall = {}, Options options = {});
  ~InlineRunner();
  InlineRunner(const InlineRunner&) = delete;
  InlineRunner& operator=(const InlineRunner&) = delete;

  /// Queues `g` for an inline run on the runner. False once stop() was
  /// called (the caller then announces the work to the group's workers).
  bool post(std::shared_ptr<CallbackGroup> g, const void* tag);
  /// Ends the runner and its watchdog (joins them; a thread left to a
  /// blocked run ends when the run returns). Queued groups go to their
  /// workers.
  void stop();
  /// Returns once nothing is queued and no run is in progress on any of the
  /// runner's threads (also one left to a run that outlived the bound).
  void wait_idle();
  /// Runs that outlived the bound so far (each moved delivery to a fresh thread).
  std::uint64_t stalls() const;
  /// True when `id` is or was one of this runner's threads.
  bool is_runner_thread(std::thread::id id) const;

  struct State;

 private:
  struct Item {
    std::shared_ptr<CallbackGroup> group;
    const void* tag = nullptr;
  };
  /// A runner thread: runs queued groups until stop() or until the watchdog
  /// gave its place to a fresh thread (generation `gen` is no longer current).
  static void run_loop(const std::shared_ptr<State>& s, std::uint64_t gen);
  /// Waits for the next item of generation `gen` (polling first); false when it is to end.
  static bool next_item(State& s, std::uint64_t gen, Item* out);
  /// The watchdog: every `bound`, hands the queue to a fresh thread if the run in progress outlived it.
  static void watch_loop(const std::shared_ptr<State>& s);
  static void start_thread(const std::shared_ptr<State>& s);

  std::shared_ptr<State> state_;
  std::thread watchdog_;
};

/// Lets a transport's delivery thread hand the callbacks of what it publishes
/// to an InlineRunner, instead of waking an executor worker (a futex wake-up
/// and a second thread per message, unless a worker polls). While one is
/// alive on a thread, publishes made there queue as usual but leave the
/// wake-up to flush(), which posts each receiving group to the runner when the
/// group may run inline now (CallbackGroup::may_run_inline: executor running,
/// no reliable publisher in the node, callbacks proven short and not paused)
/// and wakes a worker otherwise. Queues, order, drops and the callback
/// group's exclusion are the executor's own: the message goes through the
/// subscription's queue either way. Publishes made by the callbacks on the
/// runner wake workers as usual (one level deep only).
class InlineDelivery {
 public:
  /// `tag` is handed back with a stall (InlineRunner::OnStall).
  explicit InlineDelivery(InlineRunner& runner, const void* tag = nullptr);
  ~InlineDelivery();
  InlineDelivery(const InlineDelivery&) = delete;
  InlineDelivery& operator=(const InlineDelivery&) = delete;

  /// Posts or announces the work published on this thread since the last flush.
  void flush();
  /// Publisher side (CallbackGroup::announce): true when the active scope
  /// on this thread takes over announcing `g`.
  static bool defer(CallbackGroup& g);

 private:
  InlineRunner& runner_;
  const void* tag_;
  InlineDelivery* previous_;
  std::vector<std::shared_ptr<CallbackGroup>> pending_;
};

}  // namespace tinyline::bus
