// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/replay.hpp>

#include <algorithm>
#include <map>

#include <fmt/format.h>

#include <tinyline/bag/ros2.hpp>
#include <tinyline/msg/rosgraph_msgs/clock.hpp>
#include <tinyline/msg/yaml_writer.hpp>

namespace tinyline::bag {

namespace {
// Marks messages the replay itself publishes, so the capture skips them.
constexpr std::uint32_t kReplayOrigin = 0x52504c59;  // "RPLY"

using Outs = std::map<ChannelId, std::pair<std::shared_ptr<bus::GenericPublisher>, const msg::TypeSupport*>>;

// Subscribes `capture` to every topic (or the chosen ones) as it appears;
// returns the graph listener's id.
int start_capture(bus::Graph& graph, bus::Node& capture, const ReplayOptions& options, ReplayResult& result,
                  std::vector<std::shared_ptr<bus::GenericSubscription>>& subs) {
  return graph.on_topic([&](const std::shared_ptr<bus::Topic>& t) {
    const auto& want = options.capture;
    if (!want.empty() && std::find(want.begin(), want.end(), t->name()) == want.end()) return;
    auto s = capture.create_generic_subscription(
        t->name(), t->type(), bus::QoS::reliable(1),  // unbounded under the deterministic executor
        [&result, name = t->name()](const std::shared_ptr<const void>& m, const msg::TypeSupport& type,
                                    const bus::MessageInfo& info) {
          result.captured.push_back(Captured{name, &type, info.publish_time, m});
        });
    s->ignore_origin = kReplayOrigin;
    subs.push_back(std::move(s));
  });
}

// Publishers for the bag's topics (the chosen ones) of types tinyline knows;
// the others are listed in skipped_topics. False (status set) when a
// publisher cannot be made.
bool make_publishers(const Reader& reader, bus::Node& source, const ReplayOptions& options, Outs& outs,
                     std::vector<std::string>& topics, ReplayResult& result) {
  for (const auto& [id, ch] : reader.channels()) {
    if (!options.topics.empty() &&
        std::find(options.topics.begin(), options.topics.end(), ch.topic) == options.topics.end())
      continue;
    auto sc = reader.schemas().find(ch.schema_id);
    std::string why;
    const msg::TypeSupport* ts = ros2::type_support_for(sc == reader.schemas().end() ? nullptr : &sc->second, ch, &why);
    if (ts == nullptr) {
      result.skipped_topics.push_back(why);
      continue;
    }
    try {
      outs[id] = {source.create_generic_publisher(ch.topic, *ts, bus::QoS::keep_last(10)), ts};
    } catch (const std::exception& e) {
      result.status = Status(StatusCode::InvalidArgument, fmt::format("replay of {}: {}", ch.topic, e.what()));
      return false;
    }
    topics.push_back(ch.topic);
  }
  return true;
}

// Publishes the messages in log-time order, each followed by everything it
// triggers; then the tail of sim time.
void play(Reader& reader, bus::DeterministicExecutor& exec, const Outs& outs, const std::vector<std::string>& topics,
          const ReplayOptions& options, const std::shared_ptr<bus::GenericPublisher>& clock_pub, ReplayResult& result) {
  ReadOptions ro;
  ro.topics = topics;
  ro.start_time = options.start_time;
  ro.end_time = options.end_time;
  auto cursor = reader.read(ro);
  MessageView v;
  std::int64_t last = 0;
  bool any = false;
  while (!topics.empty() && cursor->next(v)) {
    const bus::Time t{static_cast<std::int64_t>(v.message.log_time)};
    exec.advance_to(t);  // the first call starts sim time (and timers) here
    if (clock_pub) {
      auto c = std::make_shared<rosgraph_msgs::msg::Clock>();
      c->clock = t.to_msg();
      clock_pub->publish(std::move(c), kReplayOrigin);
    }
    const auto& [pub, ts] = outs.at(v.message.channel_id);
    std::shared_ptr<void> m;
    try {
      m = ts->deserialize(v.message.data);
    } catch (const std::exception& e) {
      result.status = Status(StatusCode::InvalidRecord, fmt::format("message on {} at {} ns does not decode: {}",
                                                                    v.channel->topic, v.message.log_time, e.what()));
      break;
    }
    pub->publish(std::shared_ptr<const void>(std::move(m)), kReplayOrigin);
    exec.spin_until_idle();
    ++result.replayed;
    last = t.ns;
    any = true;
  }
  if (result.status.ok()) result.status = cursor->status();
  if (any && options.tail_ns > 0) exec.advance_to(bus::Time{last + options.tail_ns});
  exec.spin_until_idle();
}

}  // namespace

std::size_t ReplayResult::count(const std::string& topic) const {
  return static_cast<std::size_t>(
      std::count_if(captured.begin(), captured.end(), [&](const Captured& c) { return c.topic == topic; }));
}

std::string ReplayResult::to_yaml() const {
  std::string out;
  for (const auto& c : captured) {
    msg::YamlWriter y;
    c.type->to_yaml(c.message.get(), y);
    out +=
        "---\ntopic: " + msg::YamlWriter::quote(c.topic) + "\ntime_ns: " + std::to_string(c.time.ns) + "\nmessage:\n";
    std::string body = y.str();
    std::size_t start = 0;
    while (start < body.size()) {
      const std::size_t end = body.find('\n', start);
      out += "  " + body.substr(start, end - start) + "\n";
      if (end == std::string::npos) break;
      start = end + 1;
    }
  }
  return out;
}

Replay::Replay(const std::string& path, ReplayOptions options) : options_(std::move(options)) {
  auto f = std::make_unique<FileReadable>();
  throw_if_error(f->open(path));
  source_ = std::move(f);
  context_ = bus::Context::create(bus::ContextOptions{bus::ClockType::Sim, nullptr});
}

Replay::Replay(std::unique_ptr<Readable> source, ReplayOptions options)
    : source_(std::move(source)), options_(std::move(options)) {
  if (!source_) throw std::invalid_argument("Replay: no bag source");
  context_ = bus::Context::create(bus::ContextOptions{bus::ClockType::Sim, nullptr});
}

Replay::~Replay() = default;

void Replay::add_node(std::shared_ptr<bus::Node> node) {
  if (!node) throw std::invalid_argument("Replay::add_node: null node");
  if (node->context_ptr() != context_) {
    throw std::invalid_argument("Replay::add_node: node '" + node->full_name() +
                                "' was built with another context; build it with replay.context()");
  }
  nodes_.push_back(std::move(node));
}

ReplayResult Replay::run() {
  if (ran_) throw std::logic_error("Replay::run() called twice; make a new Replay");
  ran_ = true;
  ReplayResult result;
  Reader reader;
  result.status = reader.open(std::move(source_));
  if (!result.status.ok()) return result;
  if (!reader.has_summary()) {
    result.status = reader.scan();
    if (!result.status.ok()) return result;
  }

  bus::DeterministicExecutor exec(context_->clock());
  for (const auto& n : nodes_) exec.add_node(n);
  // Capture what the nodes publish, on every topic (or the chosen ones).
  auto capture = std::make_shared<bus::Node>(bus::NodeOptions{"bag_replay_capture", "/", {}, {}, context_, {}, {}});
  exec.add_node(capture);
  std::vector<std::shared_ptr<bus::GenericSubscription>> subs;
  auto& graph = context_->graph();
  const int listener = start_capture(graph, *capture, options_, result, subs);

  auto source = std::make_shared<bus::Node>(bus::NodeOptions{"bag_replay", "/", {}, {}, context_, {}, {}});
  exec.add_node(source);
  Outs outs;
  std::vector<std::string> topics;
  if (!make_publishers(reader, *source, options_, outs, topics, result)) {
    graph.remove_on_topic(listener);
    return result;
  }
  std::shared_ptr<bus::GenericPublisher> clock_pub;
  if (options_.publish_clock) {
    clock_pub = source->create_generic_publisher("/clock", msg::type_support<rosgraph_msgs::msg::Clock>(),
                                                 bus::QoS::keep_last(1));
  }
  play(reader, exec, outs, topics, options_, clock_pub, result);
  graph.remove_on_topic(listener);
  for (const auto& n : nodes_) n->on_stop();
  return result;
}

}  // namespace tinyline::bag
