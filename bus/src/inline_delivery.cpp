// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/executor.hpp>

#include <algorithm>
#include <utility>

namespace tinyline::bus {

namespace {
thread_local constinit InlineDelivery* tl_inline = nullptr;
}  // namespace

// ---------------------------------------------------------------------------- InlineDelivery

InlineDelivery::InlineDelivery(InlineRunner& runner, const void* tag)
    : runner_(runner), tag_(tag), previous_(tl_inline) {
  tl_inline = this;
}

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
  tl_inline = previous_;  // announce() below wakes a worker
  for (auto& g : todo) {
    if (!g->may_run_inline() || !runner_.post(g, tag_)) g->announce();
  }
  tl_inline = this;
  todo.clear();
  if (pending_.capacity() == 0) pending_.swap(todo);  // keep the allocation
}

// ---------------------------------------------------------------------------- InlineRunner

struct InlineRunner::State {
  OnStall on_stall;
  Options options;
  std::mutex mu;
  std::condition_variable work_cv;     // the runner waits for work
  std::condition_variable idle_cv;     // stop() and wait_idle() wait for runs to end
  std::condition_variable watch_cv;    // the watchdog waits for a run or for stop()
  std::atomic<std::size_t> queued{0};  // polled by an idle runner before it sleeps
  std::atomic<std::uint64_t> stalls{0};
  // Under mu.
  std::deque<Item> queue;
  bool sleeping = false;    // the runner waits on work_cv
  bool watch_idle = false;  // the watchdog waits for the next run
  bool stopping = false;
  std::uint64_t generation = 0;  // the current runner thread's; older ones end after their run
  std::thread current;
  std::vector<std::thread::id> ids;  // every runner thread so far
  // The current runner's run in progress.
  Item running;
  std::chrono::steady_clock::time_point running_since;
  std::uint64_t runs = 0;
  int in_progress = 0;  // runs on any thread, left ones too
};

InlineRunner::InlineRunner(OnStall on_stall, Options options) : state_(std::make_shared<State>()) {
  state_->on_stall = std::move(on_stall);
  state_->options = options;
  {
    std::lock_guard lk(state_->mu);
    start_thread(state_);
  }
  watchdog_ = std::thread([s = state_] { watch_loop(s); });
}

InlineRunner::~InlineRunner() { stop(); }

void InlineRunner::start_thread(const std::shared_ptr<State>& s) {
  // Under s->mu.
  const std::uint64_t gen = s->generation;
  s->current = std::thread([s, gen] { run_loop(s, gen); });
  s->ids.push_back(s->current.get_id());
}

bool InlineRunner::post(std::shared_ptr<CallbackGroup> g, const void* tag) {
  State& s = *state_;
  bool wake = false;
  {
    std::lock_guard lk(s.mu);
    if (s.stopping) return false;
    // A group queued already runs everything it holds when its turn comes.
    const bool queued = std::any_of(s.queue.begin(), s.queue.end(), [&](const Item& i) { return i.group == g; });
    if (!queued) {
      s.queue.push_back(Item{std::move(g), tag});
      s.queued.fetch_add(1, std::memory_order_release);
      wake = s.sleeping;
    }
  }
  if (wake) s.work_cv.notify_one();
  return true;
}

bool InlineRunner::next_item(State& s, std::uint64_t gen, Item* out) {
  const auto poll_until = std::chrono::steady_clock::now() + s.options.spin;
  while (s.queued.load(std::memory_order_acquire) == 0 && std::chrono::steady_clock::now() < poll_until)
    std::this_thread::yield();
  std::unique_lock lk(s.mu);
  auto ends = [&] { return s.stopping || s.generation != gen; };
  s.sleeping = true;
  s.work_cv.wait(lk, [&] { return !s.queue.empty() || ends(); });
  s.sleeping = false;
  if (ends()) return false;
  *out = std::move(s.queue.front());
  s.queue.pop_front();
  s.queued.fetch_sub(1, std::memory_order_relaxed);
  s.running = *out;
  s.running_since = std::chrono::steady_clock::now();
  ++s.runs;
  ++s.in_progress;
  if (s.watch_idle) s.watch_cv.notify_one();
  return true;
}

void InlineRunner::run_loop(const std::shared_ptr<State>& s, std::uint64_t gen) {
  Item item;
  while (next_item(*s, gen, &item)) {
    const bool ran = item.group->try_run_inline();
    if (!ran) item.group->announce();  // no scope on this thread: wakes a worker
    // More than a batch waits (a burst came while the runner was held): its
    // turn comes again after the others', as on a worker.
    const bool again = ran && item.group->has_work() && item.group->may_run_inline();
    bool replaced = false;
    {
      std::lock_guard lk(s->mu);
      replaced = s->generation != gen;  // the watchdog gave our place to a fresh thread
      if (!replaced) s->running = Item{};
      --s->in_progress;
      if (again && !s->stopping) {
        s->queue.push_back(Item{item.group, item.tag});
        s->queued.fetch_add(1, std::memory_order_release);
        if (s->sleeping) s->work_cv.notify_one();  // a fresh thread, if we were replaced
      }
    }
    s->idle_cv.notify_all();
    item = Item{};
    if (replaced) return;
  }
}

void InlineRunner::watch_loop(const std::shared_ptr<State>& s) {
  std::unique_lock lk(s->mu);
  std::uint64_t seen = 0;
  while (!s->stopping) {
    if (!s->running.group && s->runs == seen) {  // idle: sleep until a run starts
      s->watch_idle = true;
      s->watch_cv.wait(lk, [&] { return s->stopping || s->runs != seen; });
      s->watch_idle = false;
      continue;
    }
    seen = s->runs;
    s->watch_cv.wait_for(lk, s->options.bound, [&] { return s->stopping; });
    if (s->stopping || !s->running.group) continue;
    const auto held = std::chrono::steady_clock::now() - s->running_since;
    if (held < s->options.bound) continue;
    // The run keeps its thread; a fresh one takes the queue.
    const Item stalled = std::exchange(s->running, Item{});
    ++s->generation;
    s->current.detach();  // ends when its run returns
    start_thread(s);
    s->stalls.fetch_add(1, std::memory_order_relaxed);
    lk.unlock();
    if (s->on_stall) s->on_stall(stalled.tag, stalled.group->owner(), held);
    lk.lock();
  }
}

void InlineRunner::stop() {
  State& s = *state_;
  {
    std::lock_guard lk(s.mu);
    if (s.stopping) return;
    s.stopping = true;
  }
  s.work_cv.notify_all();
  s.watch_cv.notify_all();
  if (watchdog_.joinable()) watchdog_.join();
  std::deque<Item> left;
  std::thread current;
  {
    // A short run in progress ends first (its node may go right after);
    // one that outlives the bound keeps its thread, which ends after it.
    std::unique_lock lk(s.mu);
    s.idle_cv.wait_for(lk, s.options.bound, [&] { return !s.running.group; });
    current = std::move(s.current);
    left.swap(s.queue);
    if (s.running.group) {
      current.detach();
    }
  }
  if (current.joinable()) current.join();
  for (auto& i : left) i.group->announce();
}

void InlineRunner::wait_idle() {
  std::unique_lock lk(state_->mu);
  state_->idle_cv.wait(lk, [&] { return state_->queue.empty() && state_->in_progress == 0; });
}

std::uint64_t InlineRunner::stalls() const { return state_->stalls.load(std::memory_order_relaxed); }

bool InlineRunner::is_runner_thread(std::thread::id id) const {
  std::lock_guard lk(state_->mu);
  return std::find(state_->ids.begin(), state_->ids.end(), id) != state_->ids.end();
}

}  // namespace tinyline::bus
