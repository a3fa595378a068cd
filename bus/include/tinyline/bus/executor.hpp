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
#include <tinyline/bus/time.hpp>

namespace tinyline::bus {

class Executor;
class Node;
class SubscriptionBase;
class CallbackGroup;

namespace detail {
/// The queue of groups with work. Shared by an executor and the groups
/// attached to it, so a publisher racing an executor's destruction never
/// touches freed memory.
struct ReadyQueue {
  std::mutex mu;
  std::condition_variable cv;
  std::deque<std::shared_ptr<CallbackGroup>> groups;
  std::atomic<std::size_t> count{0};
  int threads = 1;
  Executor* owner = nullptr;  ///< nulled when the executor goes away (under mu)
  void push(std::shared_ptr<CallbackGroup> g);
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

/// The unit of mutual exclusion: one per node.
class CallbackGroup : public std::enable_shared_from_this<CallbackGroup> {
 public:
  explicit CallbackGroup(std::string owner) : owner_(std::move(owner)) {}

  const std::string& owner() const { return owner_; }

  /// One entry per queued message, in arrival order.
  void notify(SubscriptionBase* sub);
  void notify(const std::shared_ptr<Timer>& timer);

  /// Runs up to `max` pending callbacks; returns how many ran.
  std::size_t run(std::size_t max);

  void attach(std::shared_ptr<detail::ReadyQueue> queue, bool unbounded_reliable);
  void detach();
  /// Stops all future callbacks and waits for a running one to finish.
  void shutdown();

  /// The executor this group is attached to (nullptr if none).
  Executor* executor() const;
  /// True when the calling thread runs callbacks for this group's executor,
  /// and that executor has a single thread (so waiting on it would deadlock).
  bool drained_by_this_thread_only() const;
  bool unbounded_reliable() const { return unbounded_reliable_.load(); }
  /// True when the calling thread is inside one of this group's callbacks.
  bool running_here() const;

  /// Callback exceptions caught (and logged) so far.
  std::uint64_t errors() const { return errors_.load(); }
  std::function<void(const std::string&)> on_error;  ///< set by the node: logs the failure

 private:
  struct Entry {
    SubscriptionBase* sub = nullptr;
    std::shared_ptr<Timer> timer;
  };
  void push(Entry e);

  std::string owner_;
  mutable std::mutex mu_;
  std::condition_variable idle_;
  std::deque<Entry> pending_;
  std::vector<Entry> batch_;
  std::shared_ptr<detail::ReadyQueue> queue_;
  bool scheduled_ = false;
  bool running_ = false;
  bool dead_ = false;
  std::thread::id running_thread_;
  std::atomic<bool> unbounded_reliable_{false};
  std::atomic<std::uint64_t> errors_{0};
};

struct ExecutorOptions {
  int threads = 1;
  /// Before sleeping, an idle worker polls this long for new work: cross-thread
  /// delivery then costs a cache miss instead of a futex wake-up.
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

  /// Blocks running callbacks until stop() (from any thread or a signal-safe flag).
  virtual void spin();
  /// Runs what is ready now (and due timers), then returns.
  std::size_t spin_some();
  void stop();
  bool stopped() const { return stop_.load(); }

  int threads() const { return options_.threads; }
  Clock& clock() { return clock_; }

  // Called by nodes.
  void add_timer(const std::shared_ptr<Timer>& t, const std::shared_ptr<CallbackGroup>& g);

 protected:
  /// Calls on_start() of every node added since the last call.
  void start_pending_nodes();
  /// Takes one ready group (waiting up to `max_wait`) and runs a batch.
  bool run_once(Duration max_wait);
  /// Hands due timers to their groups; returns the next due time if any.
  std::optional<Time> fire_due_timers(Time now, bool catch_up);
  /// The worker loop of spin().
  void worker_loop();

  Clock& clock_;
  ExecutorOptions options_;
  bool unbounded_ = false;
  std::shared_ptr<detail::ReadyQueue> queue_;
  std::mutex timers_mu_;
  std::vector<std::pair<std::shared_ptr<Timer>, std::shared_ptr<CallbackGroup>>> timers_;
  std::mutex nodes_mu_;
  std::vector<std::shared_ptr<Node>> nodes_;
  std::vector<std::shared_ptr<Node>> unstarted_;
  std::atomic<bool> stop_{false};
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

}  // namespace tinyline::bus
