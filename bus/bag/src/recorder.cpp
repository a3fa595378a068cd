#include <tinyline/bag/recorder.hpp>

#include <algorithm>
#include <ctime>

#include <fmt/format.h>

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
  p.durability = q.transient_local ? ros2::QosProfile::Durability::TransientLocal : ros2::QosProfile::Durability::Volatile;
  return p;
}

// Declares the recorder's parameters with `d` as defaults and returns the result.
RecorderOptions declare(bus::Node& n, RecorderOptions d) {
  d.path = n.declare_parameter<std::string>("path", d.path, "output MCAP file (empty: tinyline_<date>_<time>.mcap)");
  d.topics = n.declare_parameter<std::vector<std::string>>("topics", d.topics, "topics to record (empty: all)");
  d.exclude = n.declare_parameter<std::vector<std::string>>("exclude", d.exclude, "topics never recorded");
  d.queue_depth = static_cast<std::size_t>(n.declare_parameter<int>(
      "queue_depth", static_cast<int>(d.queue_depth), "reliable subscription queue per topic [messages]",
      bus::ParamConstraints::range(1, 1e7)));
  const std::string comp = n.declare_parameter<std::string>(
      "compression", std::string(to_string(d.writer.writer.compression)), "chunk compression",
      bus::ParamConstraints::one_of({"none", "lz4", "zstd"}));
  d.writer.writer.compression = *parse_compression(comp);
  d.writer.writer.compression_level =
      n.declare_parameter<int>("compression_level", d.writer.writer.compression_level,
                               "lz4 0 (fast) or 1-12; zstd 1-19 (0: library default)", bus::ParamConstraints::range(0, 19));
  d.writer.writer.chunk_size_bytes = static_cast<std::uint64_t>(n.declare_parameter<int>(
                                         "chunk_size_kb", static_cast<int>(d.writer.writer.chunk_size_bytes / 1024),
                                         "uncompressed chunk size [KiB]", bus::ParamConstraints::range(1, 1 << 20))) *
                                     1024;
  d.writer.max_queue_bytes = static_cast<std::uint64_t>(n.declare_parameter<int>(
                                 "max_queue_mb", static_cast<int>(d.writer.max_queue_bytes >> 20),
                                 "serialized bytes waiting for the disk before messages are refused [MiB]",
                                 bus::ParamConstraints::range(1, 1 << 20)))
                             << 20;
  d.writer.flush_interval_s = n.declare_parameter<double>(
      "flush_interval_s", d.writer.flush_interval_s,
      "close a chunk after this long without one, so a crash loses little [s] (0: only full chunks)",
      bus::ParamConstraints::range(0.0, 3600.0));
  return d;
}

}  // namespace

Recorder::Recorder(bus::NodeOptions options) : Recorder(std::move(options), RecorderOptions{}) {}

Recorder::Recorder(bus::NodeOptions options, RecorderOptions defaults)
    : Recorder(std::move(options), std::move(defaults), nullptr) {}

Recorder::Recorder(bus::NodeOptions options, RecorderOptions defaults, std::unique_ptr<Writable> sink)
    : Node(std::move(options)), sink_(std::move(sink)) {
  opts_ = declare(*this, std::move(defaults));
}

Recorder::~Recorder() { (void)stop(); }

void Recorder::on_start() { start(); }
void Recorder::on_stop() { (void)stop(); }

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
  {
    std::lock_guard lk(mu_);
    if (!recording_.load() || !subscribed_.insert(name).second) return;
  }
  // The channel is declared with the first message, when the publishers' QoS is known.
  auto id = std::make_shared<std::optional<AsyncWriter::TopicId>>();
  auto sub = create_generic_subscription(
      name, topic->type(), bus::QoS::reliable(opts_.queue_depth),
      [this, id, name](const std::shared_ptr<const void>& m, const msg::TypeSupport& type, const bus::MessageInfo& info) {
        if (!recording_.load(std::memory_order_relaxed)) return;
        if (!*id) {
          std::vector<ros2::QosProfile> offered;
          for (const auto& node : context().graph().nodes()) {
            for (const auto& p : node.publishers) {
              if (p.topic == name) offered.push_back(to_profile(p.qos));
            }
          }
          if (offered.empty()) offered.push_back(ros2::QosProfile{});
          *id = writer_.add_topic(name, type, std::move(offered));
        }
        on_message(**id, name, m, type, info);
      });
  std::lock_guard lk(mu_);
  subs_.push_back(std::move(sub));
}

void Recorder::on_message(AsyncWriter::TopicId id, const std::string& topic, const std::shared_ptr<const void>& m,
                          const msg::TypeSupport& type, const bus::MessageInfo& info) {
  std::vector<std::uint8_t> cdr = writer_.take_buffer(id);  // a recycled one: no fresh pages to map
  type.serialize(m.get(), cdr);
  const auto log_time = static_cast<Timestamp>(std::max<std::int64_t>(0, now().ns));
  const auto pub_time = static_cast<Timestamp>(std::max<std::int64_t>(0, info.publish_time.ns));
  if (!writer_.push(id, std::move(cdr), log_time, pub_time, static_cast<std::uint32_t>(info.sequence))) {
    const auto n = drops_logged_.fetch_add(1) + 1;
    if (n == 1 || n % 1000 == 0) {
      const Status e = writer_.error();
      logger().error("dropped a message on {} ({} dropped so far): {}", topic, n,
                     e.ok() ? fmt::format("the write queue is full ({} MiB): the disk or compression cannot keep up",
                                          opts_.writer.max_queue_bytes >> 20)
                            : e.str());
    }
  }
}

Status Recorder::stop() {
  if (stopped_) return final_;
  stopped_ = true;
  if (!recording_.exchange(false)) return final_;
  context().graph().remove_on_topic(listener_);
  const RecorderStats st = stats();
  auto dropped_by_topic = [](const AsyncWriterStats& ws) {
    std::string s;
    for (const auto& [t, n] : ws.dropped_by_topic) s += fmt::format("{}{}: {}", s.empty() ? "" : ", ", t, n);
    return s;
  };
  final_ = writer_.close("tinyline_recorder", [&](const AsyncWriterStats& ws) {
    return KeyValueMap{{"recorder", full_name()},
                       {"received", std::to_string(ws.received)},
                       {"written", std::to_string(ws.written)},
                       {"dropped", std::to_string(ws.dropped)},
                       {"dropped_by_topic", dropped_by_topic(ws)},
                       {"subscription_timeouts", std::to_string(st.subscription_timeouts)}};
  });
  const AsyncWriterStats after = writer_.stats();
  if (!final_.ok()) {
    logger().error("recording to {} failed: {}", writer_.name(), final_.str());
  } else if (after.dropped != 0 || st.subscription_timeouts != 0) {
    logger().error("recorded {} messages to {}; {} dropped ({}), {} publisher timeouts", after.written, writer_.name(),
                   after.dropped, dropped_by_topic(after), st.subscription_timeouts);
  } else {
    logger().info("recorded {} messages to {} ({} bytes)", after.written, writer_.name(), after.file.file_bytes);
  }
  return final_;
}

RecorderStats Recorder::stats() const {
  const AsyncWriterStats ws = writer_.stats();
  RecorderStats s;
  s.received = ws.received;
  s.written = ws.written;
  s.dropped = ws.dropped;
  s.file_bytes = ws.file.file_bytes;
  std::lock_guard lk(mu_);
  s.topics = subs_.size();
  for (const auto& sub : subs_) s.subscription_timeouts += sub->timeouts();
  return s;
}

}  // namespace tinyline::bag
