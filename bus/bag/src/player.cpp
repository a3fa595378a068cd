// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/player.hpp>

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include <tinyline/bag/ros2.hpp>

namespace tinyline::bag {

namespace {

PlayerOptions declare(bus::Node& n, PlayerOptions d) {
  d.path = n.declare_parameter<std::string>("path", d.path, "the bag to play", bus::ParamConstraints::input_file());
  d.rate = n.declare_parameter<double>("rate", d.rate, "playback speed, x real time (0: as fast as possible)",
                                       bus::ParamConstraints::range(0.0, 1e6));
  d.loop = n.declare_parameter<bool>("loop", d.loop, "start over at the end of the bag");
  d.topics = n.declare_parameter<std::vector<std::string>>("topics", d.topics, "topics to play (empty: all)");
  d.start_offset_s =
      n.declare_parameter<double>("start_offset_s", d.start_offset_s, "skip this much of the bag's beginning [s]",
                                  bus::ParamConstraints::at_least(0.0));
  d.clock = n.declare_parameter<bool>("clock", d.clock, "publish /clock and drive sim time");
  d.clock_hz = n.declare_parameter<double>("clock_hz", d.clock_hz, "/clock rate between messages [Hz]",
                                           bus::ParamConstraints::range(0.1, 10000.0));
  return d;
}

}  // namespace

Player::Player(bus::NodeOptions options) : Player(std::move(options), PlayerOptions{}) {}

Player::Player(bus::NodeOptions options, PlayerOptions defaults) : Node(std::move(options)) {
  opts_ = declare(*this, std::move(defaults));
  if (opts_.path.empty()) {
    throw bus::ParamError(bus::SourceLocation{},
                          fmt::format("node '{}': parameter 'path' (the bag) is required", full_name()));
  }
  if (opts_.clock) clock_pub_ = create_publisher<rosgraph_msgs::msg::Clock>("/clock", bus::QoS::keep_last(1));
}

Player::~Player() { stop(); }

void Player::on_start() {
  if (thread_.joinable() || opened_) return;  // started already (the CLI opens before spinning)
  opened_ = true;
  open();
  stop_.store(false);
  thread_ = std::thread([this] { run(); });
}

void Player::on_stop() { stop(); }

void Player::stop() {
  stop_.store(true);
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void Player::open() {
  throw_if_error(reader_.open(opts_.path));
  if (!reader_.has_summary()) {
    const Status s = reader_.scan();  // channels and times of a file without a summary
    if (!s.ok()) logger().warn("{} has no summary and reading it stops early: {}", opts_.path, s.str());
  }
  const auto& st = reader_.summary().statistics;
  for (const auto& [id, ch] : reader_.channels()) {
    if (!opts_.topics.empty() && std::find(opts_.topics.begin(), opts_.topics.end(), ch.topic) == opts_.topics.end())
      continue;
    if (opts_.clock && ch.topic == "/clock") continue;  // we publish our own
    auto sc = reader_.schemas().find(ch.schema_id);
    std::string why;
    const msg::TypeSupport* ts =
        ros2::type_support_for(sc == reader_.schemas().end() ? nullptr : &sc->second, ch, &why);
    if (ts == nullptr) {
      logger().warn("not playing {}: {}", ch.topic, why);
      continue;
    }
    bus::QoS qos = bus::QoS::keep_last(10);
    auto q = ch.metadata.find(std::string(ros2::kQosKey));
    if (q != ch.metadata.end() && q->second.find("durability: 1") != std::string::npos) qos.latched();
    Out o;
    try {
      o.pub = create_generic_publisher(ch.topic, *ts, qos);
    } catch (const std::exception& e) {
      logger().warn("not playing {}: {}", ch.topic, e.what());
      continue;
    }
    o.type = ts;
    outs_[id] = std::move(o);
    if (std::find(play_topics_.begin(), play_topics_.end(), ch.topic) == play_topics_.end())
      play_topics_.push_back(ch.topic);
  }
  for (const auto& t : opts_.topics) {
    if (std::find(play_topics_.begin(), play_topics_.end(), t) == play_topics_.end())
      logger().warn("topic {} is not in {} (or has no known type)", t, opts_.path);
  }
  std::lock_guard lk(mu_);
  stats_.bag_start = st.message_start_time;
  stats_.bag_end = st.message_end_time;
  logger().info("playing {} topics of {} ({:.1f} s) at {}", play_topics_.size(), opts_.path,
                static_cast<double>(st.message_end_time - st.message_start_time) * 1e-9,
                opts_.rate > 0 ? fmt::format("{}x", opts_.rate) : std::string("full speed"));
}

bool Player::wait_until(std::chrono::steady_clock::time_point t) {
  std::unique_lock lk(mu_);
  cv_.wait_until(lk, t, [&] { return stop_.load(); });
  return !stop_.load();
}

void Player::publish_clock(Timestamp t) {
  if (!opts_.clock) return;
  const bus::Time now{static_cast<std::int64_t>(t)};
  if (clock().is_sim()) clock().set_sim_time(now);
  auto m = std::make_unique<rosgraph_msgs::msg::Clock>();
  m->clock = now.to_msg();
  clock_pub_->publish(std::move(m));
}

void Player::run() {
  using SteadyClock = std::chrono::steady_clock;
  Timestamp bag_start;
  {
    std::lock_guard lk(mu_);
    bag_start = stats_.bag_start;
  }
  const auto offset = static_cast<Timestamp>(std::llround(opts_.start_offset_s * 1e9));
  const auto clock_period = std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / opts_.clock_hz));
  Status status;
  bool first_failure = true;
  while (!stop_.load() && !play_topics_.empty()) {
    ReadOptions ro;
    ro.topics = play_topics_;
    ro.start_time = bag_start + offset;
    auto cursor = reader_.read(ro);
    MessageView v;
    bool have_origin = false;
    SteadyClock::time_point wall0;
    Timestamp bag0 = 0;
    SteadyClock::time_point next_clock;
    while (!stop_.load() && cursor->next(v)) {
      const Timestamp t = v.message.log_time;
      if (!have_origin) {
        wall0 = SteadyClock::now();
        bag0 = t;
        next_clock = wall0;
        have_origin = true;
      }
      if (opts_.rate > 0) {
        const auto due =
            wall0 + std::chrono::nanoseconds(static_cast<std::int64_t>(static_cast<double>(t - bag0) / opts_.rate));
        // Between messages, /clock ticks at clock_hz with the bag time it stands for.
        while (opts_.clock && next_clock < due) {
          if (!wait_until(next_clock)) break;
          const double elapsed = std::chrono::duration<double>(next_clock - wall0).count();
          publish_clock(bag0 + static_cast<Timestamp>(elapsed * opts_.rate * 1e9));
          next_clock += clock_period;
        }
        if (!wait_until(due)) break;
      }
      publish_clock(t);
      auto it = outs_.find(v.message.channel_id);
      if (it == outs_.end()) continue;
      bool ok = false;
      try {
        auto m = it->second.type->deserialize(v.message.data);
        ok = it->second.pub->publish(std::shared_ptr<const void>(std::move(m))).ok();
      } catch (const std::exception& e) {
        if (first_failure) {
          logger().error("{}: message on {} at {} does not decode: {}", opts_.path, v.channel->topic, t, e.what());
          first_failure = false;
        }
      }
      std::lock_guard lk(mu_);
      ++(ok ? stats_.published : stats_.failed);
      stats_.position = t;
    }
    if (!cursor->status().ok()) {
      status = cursor->status();
      logger().error("playback of {} stopped: {}", opts_.path, status.str());
      break;
    }
    if (stop_.load()) break;
    {
      std::lock_guard lk(mu_);
      ++stats_.loops;
    }
    if (!opts_.loop) break;
  }
  {
    std::lock_guard lk(mu_);
    stats_.finished = true;
    stats_.status = status;
  }
  cv_.notify_all();
}

bool Player::wait_finished(std::chrono::nanoseconds timeout) {
  std::unique_lock lk(mu_);
  return cv_.wait_for(lk, timeout, [&] { return stats_.finished; });
}

PlayerStats Player::stats() const {
  std::lock_guard lk(mu_);
  return stats_;
}

}  // namespace tinyline::bag
