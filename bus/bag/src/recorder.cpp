// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/recorder.hpp>

#include <algorithm>
#include <ctime>

#include <fmt/format.h>

#include <tinyline/bag/param_tables.hpp>
#include <tinyline/bus/param_table.hpp>

namespace tinyline::bag {

namespace {

std::string default_path() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  localtime_r(&now, &tm);
  char buf[64];
  std::strftime(buf, sizeof(buf), "tinyline_%Y%m%d_%H%M%S.mcap", &tm);
  return buf;
}

ros2::QosProfile to_profile(const bus::QoS& q) {
  ros2::QosProfile p;
  p.history = ros2::QosProfile::History::KeepLast;
  p.depth = q.depth;
  p.reliability = q.best_effort ? ros2::QosProfile::Reliability::BestEffort : ros2::QosProfile::Reliability::Reliable;
  p.durability =
      q.transient_local ? ros2::QosProfile::Durability::TransientLocal : ros2::QosProfile::Durability::Volatile;
  return p;
}

// Topic names resolved against the node's namespace (ROS 2 rules): "demo/raw"
// in the root namespace is "/demo/raw". A bad name stops the node's build at
// the line that set the parameter.
std::vector<std::string> resolved(const bus::Node& n, const std::vector<std::string>& names, const std::string& param) {
  std::vector<std::string> out;
  for (const auto& t : names) {
    try {
      out.push_back(n.resolve_topic(t));
    } catch (const std::invalid_argument& e) {
      bus::SourceLocation where;
      for (const auto& p : n.parameters())
        if (p.name == param) where = p.set_from;
      throw bus::ParamError(where, fmt::format("node '{}': parameter '{}': {}", n.full_name(), param, e.what()));
    }
  }
  return out;
}

// Declares the recorder's parameters (its table, <tinyline/bag/param_tables.hpp>)
// with `d` as defaults and returns the result, topic names resolved.
RecorderOptions declare(bus::Node& n, RecorderOptions d) {
  bus::declare_params(n, d);
  d.topics = resolved(n, d.topics, "topics");
  d.exclude = resolved(n, d.exclude, "exclude");
  return d;
}

std::string join_counts(const std::map<std::string, std::uint64_t>& counts) {
  std::string s;
  for (const auto& [t, n] : counts)
    if (n != 0) s += fmt::format("{}{}: {}", s.empty() ? "" : ", ", t, n);
  return s;
}

}  // namespace

Recorder::Recorder(bus::NodeOptions options) : Recorder(std::move(options), RecorderOptions{}) {}

Recorder::Recorder(bus::NodeOptions options, RecorderOptions defaults)
    : Recorder(std::move(options), std::move(defaults), nullptr) {}

Recorder::Recorder(bus::NodeOptions options, RecorderOptions defaults, std::unique_ptr<Writable> sink)
    : Node(std::move(options)), sink_(std::move(sink)) {
  opts_ = declare(*this, std::move(defaults));
  // A named topic that only another process publishes exists here only once
  // a transport brings it in: ask for it now, so it is there when we start.
  for (const auto& t : opts_.topics) context().graph().want(t);
}

Recorder::~Recorder() { (void)stop(); }

void Recorder::on_start() { start(); }

void Recorder::on_stop() {
  if (Status s = stop(); !s.ok()) throw BagError(std::move(s));
}

void Recorder::start() {
  if (recording_.load() || stopped_) return;
  const bool to_sink = sink_ != nullptr;
  if (!to_sink && opts_.path.empty()) opts_.path = default_path();
  Status s = to_sink ? writer_.open(std::move(sink_), opts_.writer) : writer_.open(opts_.path, opts_.writer);
  if (!s.ok()) throw BagError(std::move(s));
  if (to_sink) opts_.path = writer_.name();
  recording_.store(true);
  logger().info("recording {} to {} ({}, chunks of {} KiB)",
                opts_.topics.empty() ? std::string("all topics") : fmt::format("{}", fmt::join(opts_.topics, ", ")),
                writer_.name(), to_string(opts_.writer.writer.compression),
                opts_.writer.writer.chunk_size_bytes / 1024);
  listener_ = context().graph().on_topic([this](const std::shared_ptr<bus::Topic>& t) { subscribe(t); });
}

void Recorder::subscribe(const std::shared_ptr<bus::Topic>& topic) {
  const std::string& name = topic->name();
  if (!opts_.topics.empty() && std::find(opts_.topics.begin(), opts_.topics.end(), name) == opts_.topics.end()) return;
  if (std::find(opts_.exclude.begin(), opts_.exclude.end(), name) != opts_.exclude.end()) return;
  TopicState* t = nullptr;
  {
    std::lock_guard lk(mu_);
    if (!recording_.load() || !subscribed_.insert(name).second) return;
    topics_.push_back(std::make_unique<TopicState>());
    t = topics_.back().get();
    t->name = name;
    t->topic = topic;
    t->lost_before = topic->lost();
  }
  auto sub = create_generic_subscription(name, topic->type(), bus::QoS::reliable(opts_.queue_depth),
                                         [this, t](const std::shared_ptr<const void>& m, const msg::TypeSupport& type,
                                                   const bus::MessageInfo& info) { on_message(*t, m, type, info); });
  std::lock_guard lk(mu_);
  t->sub = std::move(sub);
}

void Recorder::on_message(TopicState& t, const std::shared_ptr<const void>& m, const msg::TypeSupport& type,
                          const bus::MessageInfo& info) {
  if (!recording_.load(std::memory_order_acquire)) {
    t.after_stop.fetch_add(1, std::memory_order_relaxed);  // counted, not lost silently
    return;
  }
  if (!t.id) {
    // The channel is declared with the first message, when the publishers' QoS is known.
    std::vector<ros2::QosProfile> offered;
    for (const auto& node : context().graph().nodes()) {
      for (const auto& p : node.publishers) {
        if (p.topic == t.name) offered.push_back(to_profile(p.qos));
      }
    }
    if (offered.empty()) offered.push_back(ros2::QosProfile{});
    t.id = writer_.add_topic(t.name, type, std::move(offered));
  }
  std::vector<std::uint8_t> cdr = writer_.take_buffer(*t.id);  // a recycled one: no fresh pages to map
  type.serialize(m.get(), cdr);
  const auto log_time = static_cast<Timestamp>(std::max<std::int64_t>(0, now().ns));
  const auto pub_time = static_cast<Timestamp>(std::max<std::int64_t>(0, info.publish_time.ns));
  if (!writer_.push(*t.id, std::move(cdr), log_time, pub_time, static_cast<std::uint32_t>(info.sequence))) {
    const auto n = drops_logged_.fetch_add(1) + 1;
    if (n == 1 || n % 1000 == 0) {
      const Status e = writer_.error();
      logger().error("dropped a message on {} ({} dropped so far): {}", t.name, n,
                     e.ok() ? fmt::format("the write queue is full ({} MiB): the disk or compression cannot keep up",
                                          opts_.writer.max_queue_bytes >> 20)
                            : e.str());
    }
  }
}

void Recorder::drain() {
  std::size_t left = 0;
  {
    std::lock_guard lk(mu_);
    for (const auto& t : topics_)
      if (t->sub) left += t->sub->queued();
  }
  // Bounded by what is queued now: publishers may go on meanwhile. A group
  // an executor thread still runs is left to it (try_run refuses). The
  // executor has usually stopped by now (a launch stops it first): what is
  // queued was published before the end all the same, so it is recorded.
  while (left > 0) {
    std::size_t ran = 0;
    if (!callback_group()->try_run_after_stop(std::min<std::size_t>(left, 64), &ran) || ran == 0) break;
    left -= std::min(left, ran);
  }
}

void Recorder::cancel_subscriptions() {
  std::lock_guard lk(mu_);
  for (const auto& t : topics_) {
    if (!t->sub) continue;
    t->discarded.fetch_add(t->sub->cancel(), std::memory_order_relaxed);
  }
}

Status Recorder::stop() {
  if (stopped_) return final_;
  stopped_ = true;
  if (!recording_.load()) return final_;
  context().graph().remove_on_topic(listener_);
  drain();                  // what the queues hold was accepted: record it
  recording_.store(false);  // callbacks from here on are counted as dropped
  cancel_subscriptions();   // and so is what is still queued
  final_ = writer_.close("tinyline_recorder", [this](const AsyncWriterStats& ws) { return metadata(ws); });
  report(final_);
  return final_;
}

KeyValueMap Recorder::metadata(const AsyncWriterStats& ws) const {
  RecorderStats st = stats();
  return KeyValueMap{{"recorder", full_name()},
                     {"received", std::to_string(ws.received)},
                     {"written", std::to_string(ws.written)},
                     {"dropped", std::to_string(st.dropped)},
                     {"dropped_by_topic", join_counts(st.dropped_by_topic)},
                     {"subscription_timeouts", std::to_string(st.subscription_timeouts)},
                     {"lost_upstream", std::to_string(st.lost_upstream)}};
}

void Recorder::report(const Status& final_status) const {
  const RecorderStats st = stats();
  if (!final_status.ok()) {
    logger().error("recording to {} failed: {}; what was recorded is in {}.part (tinyline bag recover)", writer_.name(),
                   final_status.str(), writer_.name());
  } else if (st.dropped != 0) {
    logger().error("recorded {} messages to {}; {} dropped ({}), {} of them when a publisher found the queue full",
                   st.written, writer_.name(), st.dropped, join_counts(st.dropped_by_topic), st.subscription_timeouts);
  } else {
    logger().info("recorded {} messages to {} ({} bytes)", st.written, writer_.name(), st.file_bytes);
  }
  std::lock_guard lk(mu_);
  for (const auto& name : opts_.topics) {
    if (subscribed_.count(name) == 0) logger().warn("topic {} never appeared: nothing recorded on it", name);
  }
}

RecorderStats Recorder::stats() const {
  const AsyncWriterStats ws = writer_.stats();
  RecorderStats s;
  s.received = ws.received;
  s.written = ws.written;
  s.file_bytes = ws.file.file_bytes;
  s.dropped_by_topic = ws.dropped_by_topic;
  std::lock_guard lk(mu_);
  s.topics = topics_.size();
  for (const auto& t : topics_) {
    const std::uint64_t timeouts = t->sub ? t->sub->timeouts() : 0;
    // Published elsewhere and lost on the way (DDS said so): never here, still not recorded.
    const std::uint64_t lost = t->topic ? t->topic->lost() - t->lost_before : 0;
    s.subscription_timeouts += timeouts;
    s.lost_upstream += lost;
    s.dropped_by_topic[t->name] += timeouts + lost + t->after_stop.load() + t->discarded.load();
  }
  for (const auto& [topic, n] : s.dropped_by_topic) s.dropped += n;
  return s;
}

}  // namespace tinyline::bag
