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
thread_local const detail::ReadyQueue* tl_queue = nullptr;

struct QueueScope {
  explicit QueueScope(const detail::ReadyQueue* q) : prev(tl_queue) { tl_queue = q; }
  ~QueueScope() { tl_queue = prev; }
  const detail::ReadyQueue* prev;
};
}  // namespace

Executor* current_executor() {
  return tl_queue ? tl_queue->owner : nullptr;
}

void detail::ReadyQueue::push(std::shared_ptr<CallbackGroup> g) {
  {
    std::lock_guard lk(mu);
    groups.push_back(std::move(g));
    count.fetch_add(1, std::memory_order_release);
  }
  cv.notify_one();
}

// ---------------------------------------------------------------------------- CallbackGroup

void CallbackGroup::push(Entry e) {
  std::shared_ptr<detail::ReadyQueue> q;
  {
    std::lock_guard lk(mu_);
    if (dead_) return;
    pending_.push_back(std::move(e));
    if (!scheduled_ && !running_ && queue_) {
      scheduled_ = true;
      q = queue_;
    }
  }
  if (q) q->push(shared_from_this());
}

void CallbackGroup::notify(SubscriptionBase* sub) { push(Entry{sub, nullptr}); }
void CallbackGroup::notify(const std::shared_ptr<Timer>& timer) { push(Entry{nullptr, timer}); }

std::size_t CallbackGroup::run(std::size_t max) {
  {
    std::lock_guard lk(mu_);
    scheduled_ = false;
    if (dead_ || running_) return 0;
    running_ = true;
    running_thread_ = std::this_thread::get_id();
    const std::size_t n = std::min(max, pending_.size());
    for (std::size_t i = 0; i < n; ++i) {
      batch_.push_back(std::move(pending_.front()));
      pending_.pop_front();
    }
  }
  std::size_t ran = 0;
  for (auto& e : batch_) {
    try {
      if (e.sub != nullptr) {
        if (e.sub->execute_one()) ++ran;
      } else if (e.timer && !e.timer->cancelled()) {
        e.timer->fired_.fetch_add(1, std::memory_order_relaxed);
        e.timer->cb_();
        ++ran;
      }
    } catch (const std::exception& ex) {
      errors_.fetch_add(1);
      if (on_error) on_error(ex.what());
    } catch (...) {
      errors_.fetch_add(1);
      if (on_error) on_error("unknown exception");
    }
  }
  batch_.clear();
  std::shared_ptr<detail::ReadyQueue> q;
  {
    std::lock_guard lk(mu_);
    running_ = false;
    running_thread_ = {};
    if (!dead_ && !pending_.empty() && queue_ && !scheduled_) {
      scheduled_ = true;
      q = queue_;
    }
  }
  idle_.notify_all();
  if (q) q->push(shared_from_this());
  return ran;
}

void CallbackGroup::attach(std::shared_ptr<detail::ReadyQueue> queue, bool unbounded_reliable) {
  std::shared_ptr<detail::ReadyQueue> q;
  {
    std::lock_guard lk(mu_);
    if (queue_ && queue_ != queue) throw std::logic_error("node '" + owner_ + "' is already in an executor");
    queue_ = std::move(queue);
    unbounded_reliable_.store(unbounded_reliable);
    if (!pending_.empty() && !scheduled_ && !running_ && !dead_) {
      scheduled_ = true;
      q = queue_;
    }
  }
  if (q) q->push(shared_from_this());
}

void CallbackGroup::detach() {
  std::unique_lock lk(mu_);
  queue_.reset();
  scheduled_ = false;
}

void CallbackGroup::shutdown() {
  std::unique_lock lk(mu_);
  dead_ = true;
  pending_.clear();
  if (running_thread_ != std::this_thread::get_id()) {
    idle_.wait(lk, [&] { return !running_; });
  }
  queue_.reset();
}

Executor* CallbackGroup::executor() const {
  std::shared_ptr<detail::ReadyQueue> q;
  {
    std::lock_guard lk(mu_);
    q = queue_;
  }
  if (!q) return nullptr;
  std::lock_guard lk(q->mu);
  return q->owner;
}

bool CallbackGroup::drained_by_this_thread_only() const {
  std::lock_guard lk(mu_);
  return queue_ && queue_.get() == tl_queue && queue_->threads == 1;
}

bool CallbackGroup::running_here() const {
  std::lock_guard lk(mu_);
  return running_ && running_thread_ == std::this_thread::get_id();
}

// ---------------------------------------------------------------------------- Executor

Executor::Executor(Clock& clock, ExecutorOptions options)
    : clock_(clock), options_(options), queue_(std::make_shared<detail::ReadyQueue>()) {
  if (options_.threads < 1) throw std::invalid_argument("an executor needs at least one thread");
  queue_->threads = options_.threads;
  queue_->owner = this;
  // Sim-time changes may make timers due: wake a sleeping worker.
  clock_listener_ = clock_.add_listener([q = queue_] { q->cv.notify_all(); });
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
  std::lock_guard lk(queue_->mu);
  queue_->owner = nullptr;
  queue_->groups.clear();
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
  node->callback_group()->attach(queue_, unbounded_);
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
    timers_.emplace_back(t, g);
  }
  queue_->cv.notify_all();
}

void Executor::start_pending_nodes() {
  std::vector<std::shared_ptr<Node>> todo;
  {
    std::lock_guard lk(nodes_mu_);
    todo.swap(unstarted_);
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
  queue_->cv.notify_all();
}

std::optional<Time> Executor::fire_due_timers(Time now, bool catch_up) {
  std::vector<std::pair<std::shared_ptr<Timer>, std::shared_ptr<CallbackGroup>>> due;
  std::optional<Time> next;
  {
    std::lock_guard lk(timers_mu_);
    std::erase_if(timers_, [](const auto& p) { return p.first->cancelled(); });
    if (!clock_.started()) return std::nullopt;
    for (auto& [t, g] : timers_) {
      if (!t->anchored_ || now < t->next_due_ - t->period_) {  // first time, or time went back
        t->next_due_ = now + t->period_;
        t->anchored_ = true;
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

bool Executor::run_once(Duration max_wait) {
  std::shared_ptr<CallbackGroup> g;
  auto try_pop = [&] {
    std::lock_guard lk(queue_->mu);
    if (queue_->groups.empty()) return false;
    g = std::move(queue_->groups.front());
    queue_->groups.pop_front();
    queue_->count.fetch_sub(1, std::memory_order_relaxed);
    return true;
  };
  if (queue_->count.load(std::memory_order_acquire) == 0 && max_wait.count() > 0) {
    // Poll briefly before sleeping: a message from another thread then costs a
    // cache miss, not a futex wake-up.
    const auto spin_end = std::chrono::steady_clock::now() + std::min(options_.spin, max_wait);
    while (queue_->count.load(std::memory_order_acquire) == 0 && !stop_.load(std::memory_order_relaxed) &&
           std::chrono::steady_clock::now() < spin_end) {
      for (int i = 0; i < 32; ++i) TL_CPU_RELAX();
    }
  }
  if (!try_pop()) {
    if (max_wait.count() <= 0) return false;
    std::unique_lock lk(queue_->mu);
    queue_->cv.wait_for(lk, max_wait, [&] { return !queue_->groups.empty() || stop_.load(); });
    if (queue_->groups.empty()) return false;
    g = std::move(queue_->groups.front());
    queue_->groups.pop_front();
    queue_->count.fetch_sub(1, std::memory_order_relaxed);
  }
  QueueScope scope(queue_.get());
  g->run(options_.batch);
  return true;
}

void Executor::worker_loop() {
  constexpr Duration kIdleWait = std::chrono::milliseconds(100);
  while (!stop_.load()) {
    const Time now = clock_.now();
    const auto next = fire_due_timers(now, clock_.is_sim());
    Duration wait = kIdleWait;
    if (next && !clock_.is_sim()) wait = std::clamp<Duration>(*next - now, Duration::zero(), kIdleWait);
    run_once(wait);
  }
}

void Executor::spin() {
  stop_.store(false);
  start_pending_nodes();
  worker_loop();
}

std::size_t Executor::spin_some() {
  start_pending_nodes();
  fire_due_timers(clock_.now(), clock_.is_sim());
  std::size_t n = 0;
  while (run_once(Duration::zero())) ++n;
  return n;
}

void MultiThreadedExecutor::spin() {
  stop_.store(false);
  start_pending_nodes();
  std::vector<std::thread> workers;
  for (int i = 1; i < options_.threads; ++i) workers.emplace_back([this] { worker_loop(); });
  worker_loop();
  for (auto& w : workers) w.join();
}

// ---------------------------------------------------------------------------- DeterministicExecutor

DeterministicExecutor::DeterministicExecutor(Clock& clock) : Executor(clock, ExecutorOptions{1, Duration::zero(), 1}) {
  if (!clock.is_sim()) throw std::invalid_argument("DeterministicExecutor needs a context with a sim clock");
  unbounded_ = true;
}

std::size_t DeterministicExecutor::spin_until_idle() {
  start_pending_nodes();
  std::size_t n = 0;
  while (true) {
    std::shared_ptr<CallbackGroup> g;
    {
      std::lock_guard lk(queue_->mu);
      if (queue_->groups.empty()) break;
      g = std::move(queue_->groups.front());
      queue_->groups.pop_front();
      queue_->count.fetch_sub(1, std::memory_order_relaxed);
    }
    QueueScope scope(queue_.get());
    n += g->run(1);
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
