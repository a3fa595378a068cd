// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/graph.hpp>

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

#include <tinyline/bus/executor.hpp>

namespace tinyline::bus {

// ---------------------------------------------------------------------------- SubscriptionBase

SubscriptionBase::SubscriptionBase(std::string topic, const msg::TypeSupport* type, QoS qos,
                                   std::shared_ptr<CallbackGroup> group)
    : topic_(std::move(topic)), type_(type), qos_(qos), group_(std::move(group)), ring_(std::min(qos.depth, kMaxRing)) {
  if (qos_.depth == 0) throw std::invalid_argument("subscription to '" + topic_ + "': QoS depth must be at least 1");
}

bool SubscriptionBase::would_wait() {
  return qos_.history == QoS::History::Reliable && !group_->unbounded_reliable() && full();
}

bool SubscriptionBase::enqueue(std::shared_ptr<const void> msg, const MessageInfo& info, std::string* why, Wait wait) {
  if (ignore_origin != 0 && info.origin == ignore_origin) return true;
  CallbackGroup& g = *group_;
  if (cancelled_.load(std::memory_order_acquire) || g.dead()) return true;
  if (full() && !(wait == Wait::Never && qos_.history == QoS::History::Reliable)) {
    if (qos_.history == QoS::History::KeepLast) {
      // Drop the oldest. The worker may take one meanwhile; either way the
      // queue ends at most `depth` long, and only what we pop counts as dropped.
      QueuedMessage old;
      while (full() && pop(&old)) {
        dropped_.fetch_add(1, std::memory_order_relaxed);
        old.msg.reset();
      }
    } else if (!g.unbounded_reliable()) {
      switch (wait_for_room(g, why)) {
        case Room::Made: break;
        case Room::Gone: return true;
        case Room::Failed: return false;
      }
    }
  }
  QueuedMessage m{std::move(msg), info};
  push(m, g.next_stamp());
  received_.fetch_add(1, std::memory_order_relaxed);
  g.announce();
  return true;
}

SubscriptionBase::Room SubscriptionBase::wait_for_room(CallbackGroup& g, std::string* why) {
  // Reliable: wait for room, unless the executor that drains the queue is
  // stopping or this thread is inside the subscriber's own callback. A thread
  // of the subscriber's executor runs the subscriber itself while it is
  // idle: publishers blocked on every worker must not keep it from running.
  auto fail = [&](std::string reason) {
    timeouts_.fetch_add(1, std::memory_order_relaxed);
    if (why) *why = std::move(reason);
    return Room::Failed;
  };
  if (g.executor_stopping()) return fail(stopping_reason(g));
  if (g.running_here()) {
    return fail(
        fmt::format("reliable queue of {} for '{}' is full ({}) and the publisher runs on the thread that drains it; "
                    "raise the depth or run the subscriber on another executor thread",
                    topic_, g.owner(), qos_.depth));
  }
  // A worker polls often enough that a short wait costs nothing; it bounds
  // how long a publisher sleeps while the subscriber could run here.
  constexpr auto kLook = std::chrono::milliseconds(1);
  const auto deadline = std::chrono::steady_clock::now() + qos_.max_block;
  auto has_room = [&] {
    return size() < qos_.depth || cancelled_.load(std::memory_order_acquire) || g.dead() || g.executor_stopping();
  };
  // Announce the wait before reading the size: the worker advances the
  // head before reading `waiting_` (both seq_cst), so one sees the other.
  waiting_.fetch_add(1, std::memory_order_seq_cst);
  bool room = false;
  for (;;) {
    if (has_room()) {
      room = true;
      break;
    }
    if (g.run_for_waiting_publisher()) continue;
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline) break;
    std::unique_lock lk(slow_mu_);
    room_.wait_until(lk, std::min(deadline, now + kLook), has_room);
  }
  waiting_.fetch_sub(1, std::memory_order_relaxed);
  if (room && (cancelled_.load(std::memory_order_acquire) || g.dead())) return Room::Gone;
  if (g.executor_stopping() && size() >= qos_.depth) return fail(stopping_reason(g));
  if (!room) {
    return fail(fmt::format("reliable queue of {} for '{}' stayed full ({}) for {:.3f} s", topic_, g.owner(),
                            qos_.depth, to_seconds(qos_.max_block)));
  }
  return Room::Made;
}

void SubscriptionBase::push(QueuedMessage& m, std::uint64_t stamp) {
  if (overflow_size_.load(std::memory_order_acquire) == 0 && ring_.try_push(m, stamp)) return;
  std::lock_guard lk(slow_mu_);
  overflow_.push_back(Stamped{std::move(m), stamp});
  overflow_size_.fetch_add(1, std::memory_order_seq_cst);  // seq_cst: see MessageRing::try_push
}

bool SubscriptionBase::pop(QueuedMessage* out) {
  if (ring_.try_pop(out)) return true;
  // The overflow holds only messages newer than the ring's: take from it only
  // once the ring is empty, not while a publisher is still writing its head.
  if (overflow_size_.load(std::memory_order_acquire) == 0 || ring_.size() != 0) return false;
  std::lock_guard lk(slow_mu_);
  // Again under the lock: while this thread waited for it, a publisher may
  // have put a message in the ring and its next one in the overflow, and
  // another consumer taken what was ahead of that one. The overflow's front
  // is then newer than the ring's message of the same publisher.
  if (overflow_.empty() || ring_.size() != 0) return false;
  *out = std::move(overflow_.front().m);
  overflow_.pop_front();
  overflow_size_.fetch_sub(1, std::memory_order_seq_cst);
  return true;
}

std::optional<std::uint64_t> SubscriptionBase::front_stamp() {
  if (auto s = ring_.front_stamp()) return s;
  if (overflow_size_.load(std::memory_order_acquire) == 0 || ring_.size() != 0) return std::nullopt;
  std::lock_guard lk(slow_mu_);
  if (overflow_.empty() || ring_.size() != 0) return std::nullopt;  // as in pop()
  return overflow_.front().stamp;
}

void SubscriptionBase::made_room() {
  if (qos_.history != QoS::History::Reliable) return;
  if (waiting_.load(std::memory_order_seq_cst) == 0) return;
  std::lock_guard lk(slow_mu_);  // a publisher between its check and its wait holds it
  room_.notify_one();
}

std::size_t SubscriptionBase::clear() {
  std::size_t n = 0;
  QueuedMessage m;
  while (ring_.try_pop(&m)) {
    m.msg.reset();
    ++n;
  }
  std::lock_guard lk(slow_mu_);
  n += overflow_.size();
  overflow_.clear();
  overflow_size_.store(0, std::memory_order_seq_cst);
  return n;
}

std::size_t SubscriptionBase::queued() const { return size(); }

std::string SubscriptionBase::stopping_reason(const CallbackGroup& g) const {
  return fmt::format("reliable queue of {} for '{}' is full ({}) and the executor that drains it is stopping", topic_,
                     g.owner(), qos_.depth);
}

void SubscriptionBase::wake_publishers() {
  std::lock_guard lk(slow_mu_);
  room_.notify_all();
}

std::size_t SubscriptionBase::cancel() {
  cancelled_.store(true, std::memory_order_seq_cst);
  const std::size_t discarded = clear();
  {
    std::lock_guard lk(slow_mu_);
    room_.notify_all();
  }
  group_->remove_subscription(this);
  return discarded;
}

// ---------------------------------------------------------------------------- Topic

std::shared_ptr<const Topic::SubList> Topic::snapshot() const {
  std::lock_guard lk(mu_);
  return subs_;
}

bool Topic::would_wait() const {
  const auto subs = snapshot();
  for (const auto& s : *subs)
    if (s->would_wait()) return true;
  return false;
}

PublishStatus Topic::publish(std::shared_ptr<const void> msg, const MessageInfo& info, std::string* why, Wait wait) {
  published_.fetch_add(1, std::memory_order_relaxed);
  if (latched_depth_.load(std::memory_order_relaxed) != 0) {
    std::lock_guard lk(mu_);
    latched_.push_back(QueuedMessage{msg, info});
    while (latched_.size() > latched_depth_.load()) latched_.pop_front();
  }
  const auto subs = snapshot();
  const bool taps = has_taps_.load(std::memory_order_acquire);
  PublishStatus st;
  for (std::size_t i = 0; i < subs->size(); ++i) {
    // The last one without taps takes the publisher's reference: one
    // reference-count round trip less, and the worker alone touches the count.
    const bool last = i + 1 == subs->size() && !taps;
    if ((*subs)[i]->enqueue(last ? std::move(msg) : msg, info, why, wait)) {
      ++st.delivered;
    } else {
      ++st.failed;
    }
  }
  if (taps) {
    std::shared_lock lk(taps_mu_);
    for (const auto& [id, tap] : taps_) tap(msg, info);
  }
  return st;
}

int Topic::add_tap(Tap tap) {
  std::deque<QueuedMessage> latched;
  {
    std::lock_guard lk(mu_);
    latched = latched_;
  }
  for (const auto& m : latched) tap(m.msg, m.info);
  std::unique_lock lk(taps_mu_);
  const int id = next_tap_++;
  taps_.emplace_back(id, std::move(tap));
  has_taps_.store(true, std::memory_order_release);
  return id;
}

void Topic::remove_tap(int id) {
  std::unique_lock lk(taps_mu_);  // waits for a publish() inside the tap
  std::erase_if(taps_, [id](const auto& p) { return p.first == id; });
  has_taps_.store(!taps_.empty(), std::memory_order_release);
}

void Topic::add_subscription(const std::shared_ptr<SubscriptionBase>& s) {
  if (s->type().name != type_->name) {
    throw std::invalid_argument(
        fmt::format("topic '{}' has type {}, cannot subscribe with {}", name_, type_->name, s->type().name));
  }
  std::deque<QueuedMessage> latched;
  {
    std::lock_guard lk(mu_);
    auto next = std::make_shared<SubList>(*subs_);
    next->push_back(s);
    subs_ = std::move(next);
    if (s->qos().transient_local) latched = latched_;
  }
  for (auto& m : latched) s->enqueue(m.msg, m.info, nullptr);
}

void Topic::remove_subscription(const SubscriptionBase* s) {
  std::lock_guard lk(mu_);
  auto next = std::make_shared<SubList>();
  for (const auto& x : *subs_) {
    if (x.get() == s) {
      gone_dropped_ += x->dropped();
      gone_timeouts_ += x->timeouts();
    } else {
      next->push_back(x);
    }
  }
  subs_ = std::move(next);
}

void Topic::add_publisher(const QoS& offered) {
  publishers_.fetch_add(1);
  if (offered.transient_local) {
    std::lock_guard lk(mu_);
    latched_depth_.store(std::max(latched_depth_.load(), offered.depth));
  }
}

void Topic::remove_publisher() { publishers_.fetch_sub(1); }

std::size_t Topic::subscription_count() const { return snapshot()->size(); }

std::uint64_t Topic::dropped() const {
  std::lock_guard lk(mu_);
  std::uint64_t n = gone_dropped_ + lost();
  for (const auto& s : *subs_) n += s->dropped();
  return n;
}

std::uint64_t Topic::timeouts() const {
  std::lock_guard lk(mu_);
  std::uint64_t n = gone_timeouts_;
  for (const auto& s : *subs_) n += s->timeouts();
  return n;
}

// ---------------------------------------------------------------------------- Graph

std::shared_ptr<Topic> Graph::topic(const std::string& name, const msg::TypeSupport& type) {
  std::shared_ptr<Topic> created;
  std::vector<std::function<void(const std::shared_ptr<Topic>&)>> fns;
  {
    std::lock_guard lk(mu_);
    for (const auto& t : topics_) {
      if (t->name() == name) {
        if (t->type().name != type.name) {
          throw std::invalid_argument(
              fmt::format("topic '{}' already has type {}; cannot use it as {}", name, t->type().name, type.name));
        }
        return t;
      }
    }
    created = std::make_shared<Topic>(name, &type);
    topics_.push_back(created);
    for (auto& [id, fn] : listeners_) fns.push_back(fn);
  }
  for (auto& fn : fns) fn(created);
  return created;
}

std::shared_ptr<Topic> Graph::find(const std::string& name) const {
  std::lock_guard lk(mu_);
  for (const auto& t : topics_)
    if (t->name() == name) return t;
  return nullptr;
}

std::vector<TopicInfo> Graph::topics() const {
  std::vector<std::shared_ptr<Topic>> ts;
  {
    std::lock_guard lk(mu_);
    ts = topics_;
  }
  std::vector<TopicInfo> out;
  for (const auto& t : ts) {
    out.push_back(TopicInfo{t->name(), std::string(t->type().name), t->publisher_count(), t->subscription_count(),
                            t->published(), t->dropped(), t->timeouts()});
  }
  std::sort(out.begin(), out.end(), [](const TopicInfo& a, const TopicInfo& b) { return a.name < b.name; });
  return out;
}

std::vector<NodeInfo> Graph::nodes() const {
  std::vector<std::function<NodeInfo()>> fns;
  {
    std::lock_guard lk(mu_);
    for (const auto& [k, fn] : nodes_) fns.push_back(fn);
  }
  std::vector<NodeInfo> out;
  for (auto& fn : fns) out.push_back(fn());
  std::sort(out.begin(), out.end(), [](const NodeInfo& a, const NodeInfo& b) { return a.full_name < b.full_name; });
  return out;
}

int Graph::on_topic(std::function<void(const std::shared_ptr<Topic>&)> fn) {
  std::vector<std::shared_ptr<Topic>> existing;
  int id;
  {
    std::lock_guard lk(mu_);
    id = next_listener_++;
    listeners_.emplace_back(id, fn);
    existing = topics_;
  }
  for (const auto& t : existing) fn(t);
  return id;
}

void Graph::remove_on_topic(int id) {
  std::lock_guard lk(mu_);
  std::erase_if(listeners_, [id](const auto& p) { return p.first == id; });
}

int Graph::on_endpoints_changed(std::function<void(const std::string&)> fn) {
  std::lock_guard lk(mu_);
  const int id = next_listener_++;
  endpoint_listeners_.emplace_back(id, std::move(fn));
  return id;
}

void Graph::remove_on_endpoints_changed(int id) {
  std::lock_guard lk(mu_);
  std::erase_if(endpoint_listeners_, [id](const auto& p) { return p.first == id; });
}

void Graph::endpoints_changed(const std::string& topic) {
  std::vector<std::function<void(const std::string&)>> fns;
  {
    std::lock_guard lk(mu_);
    for (auto& [id, fn] : endpoint_listeners_) fns.push_back(fn);
  }
  for (auto& fn : fns) fn(topic);  // outside the lock: a listener may create endpoints itself
}

void Graph::want(const std::string& topic) {
  {
    std::lock_guard lk(mu_);
    if (std::find(wanted_.begin(), wanted_.end(), topic) != wanted_.end()) return;
    wanted_.push_back(topic);
  }
  endpoints_changed(topic);
}

bool Graph::wanted(const std::string& topic) const {
  std::lock_guard lk(mu_);
  return std::find(wanted_.begin(), wanted_.end(), topic) != wanted_.end();
}

std::vector<std::string> Graph::wants() const {
  std::lock_guard lk(mu_);
  return wanted_;
}

void Graph::add_node(const void* key, std::function<NodeInfo()> describe) {
  std::lock_guard lk(mu_);
  nodes_.emplace_back(key, std::move(describe));
}

void Graph::remove_node(const void* key) {
  std::lock_guard lk(mu_);
  std::erase_if(nodes_, [key](const auto& p) { return p.first == key; });
}

// ---------------------------------------------------------------------------- RateMonitor

std::vector<RateMonitor::Row> RateMonitor::sample(const Graph& g, Time wall_now) {
  std::vector<Row> rows;
  const double dt = have_last_ ? (wall_now - last_time_).count() * 1e-9 : 0.0;
  std::vector<std::pair<std::string, std::uint64_t>> counts;
  for (auto& info : g.topics()) {
    Row r;
    r.info = info;
    if (dt > 0) {
      for (const auto& [name, n] : last_counts_) {
        if (name == info.name) {
          r.rate_hz = static_cast<double>(info.published - n) / dt;
          break;
        }
      }
    }
    counts.emplace_back(info.name, info.published);
    rows.push_back(std::move(r));
  }
  last_counts_ = std::move(counts);
  last_time_ = wall_now;
  have_last_ = true;
  return rows;
}

}  // namespace tinyline::bus
