// SPDX-License-Identifier: Apache-2.0
#include "sim/nodes/nodes.hpp"

#include <cmath>
#include <limits>
#include <variant>

#include <tinyline/msg/eigen.hpp>

#include "parts.hpp"

namespace tinyline::sim::nodes {

namespace msgs = tinyline_msgs::msg;

namespace {

std::int16_t wire(double v) { return static_cast<std::int16_t>(std::clamp(std::lround(v * 10.0), -32768L, 32767L)); }

}  // namespace

void to_msg(const SensorSet& set, msgs::RawScan& out) {
  out.set_index = static_cast<std::uint32_t>(set.index);
  out.temperature_c = static_cast<float>(set.temperature_c);
  const std::size_t n = set.readouts.empty() ? 0 : set.readouts.front().a.size();
  out.pixels = static_cast<std::uint16_t>(n);
  out.pulses.clear();
  out.a.clear();
  out.b.clear();
  out.a.reserve(n * set.readouts.size());
  out.b.reserve(n * set.readouts.size());
  for (const auto& r : set.readouts) {
    out.pulses.push_back(static_cast<std::uint16_t>(r.pulses));
    for (std::size_t i = 0; i < n; ++i) {
      out.a.push_back(wire(r.a[i]));
      out.b.push_back(wire(r.b[i]));
    }
  }
}

void to_msg(const SensorSet& set, const std::string& sensor, const World& world, msgs::ScanTruth& out) {
  out.sensor = sensor;
  out.set_index = set.index;
  out.temperature_c = static_cast<float>(set.true_temperature_c);
  out.sensor_pose = tinyline::msg::to_pose(set.T_world_sensor);
  out.crosstalk_pulses = static_cast<std::uint32_t>(std::max(0, set.crosstalk_pulses));
  const std::size_t n = set.truth.size();
  out.range_m.resize(n);
  out.object.resize(n);
  out.material.resize(n);
  out.incidence_rad.resize(n);
  out.flags.resize(n);
  const std::size_t dark = n >= 16 ? 8 : 0;
  for (std::size_t i = 0; i < n; ++i) {
    const PixelTruth& t = set.truth[i];
    out.range_m[i] = static_cast<float>(t.range_m);
    out.object[i] = t.object;
    out.material[i] = t.material;
    out.incidence_rad[i] = static_cast<float>(t.incidence_rad);
    out.flags[i] = static_cast<std::uint8_t>((t.lit ? msgs::ScanTruth::FLAG_LIT : 0) |
                                             (t.mixed ? msgs::ScanTruth::FLAG_MIXED : 0) |
                                             ((i < dark || i + dark >= n) ? msgs::ScanTruth::FLAG_DARK : 0));
  }
  out.objects.clear();
  for (std::size_t k = 0; k < world.size(); ++k) out.objects.push_back(world.object(static_cast<ObjectId>(k)).name);
  out.materials.clear();
  for (const auto& m : world.materials().all()) out.materials.push_back(m.name);
}

void to_msg(const Scene& scene, msgs::SceneTruth& out) {
  out.scene = scene.name;
  out.objects.clear();
  const World& w = scene.world;
  for (std::size_t k = 0; k < w.size(); ++k) {
    const Object& o = w.object(static_cast<ObjectId>(k));
    msgs::ObjectTruth t;
    t.name = o.name;
    t.shape = shape_name(o.shape);
    t.material = w.materials().get(o.material).name;
    t.pose = tinyline::msg::to_pose(o.T_world_object);
    std::visit(
        [&](const auto& s) {
          using S = std::decay_t<decltype(s)>;
          if constexpr (std::is_same_v<S, PlaneShape>)
            t.dimensions = {s.size_m.x(), s.size_m.y()};
          else if constexpr (std::is_same_v<S, BoxShape>)
            t.dimensions = {s.size_m.x(), s.size_m.y(), s.size_m.z()};
          else if constexpr (std::is_same_v<S, SphereShape>)
            t.dimensions = {s.radius_m};
          else if constexpr (std::is_same_v<S, CylinderShape>)
            t.dimensions = {s.radius_m, s.length_m};
          else if constexpr (std::is_same_v<S, RodShape>)
            t.dimensions = {s.radius_m, s.p0.x(), s.p0.y(), s.p0.z(), s.p1.x(), s.p1.y(), s.p1.z()};
          else
            t.dimensions.clear();
        },
        o.shape);
    out.objects.push_back(std::move(t));
  }
  out.annotation_keys.clear();
  out.annotation_sizes.clear();
  out.annotation_values.clear();
  for (const auto& [k, v] : scene.truth) {
    out.annotation_keys.push_back(k);
    out.annotation_sizes.push_back(static_cast<std::uint32_t>(v.size()));
    out.annotation_values.insert(out.annotation_values.end(), v.begin(), v.end());
  }
}

// ---------------------------------------------------------------------------- virtual_sensor

VirtualSensorNode::VirtualSensorNode(bus::NodeOptions o) : bus::Node(std::move(o)) {
  scene_path_ =
      declare_parameter<std::string>("scene", "", "scene YAML (sim/config/scenes/...) [required]", scene_file());
  sensor_name_ = declare_parameter<std::string>("sensor", "", "sensor name in the scene; empty: the first");
  frame_id_ = declare_parameter<std::string>("frame_id", "", "frame of the published scans; empty: the sensor's name");
  publish_truth_ = declare_parameter("publish_truth", true, "also publish scan_truth for every set");
  power_on_age_s_ = declare_parameter("power_on_age_s", SystemOptions{}.power_on_age_s,
                                      "sensor time at start [s]: 0 = cold power-on (live warm-up), 3600 = warm",
                                      bus::ParamConstraints::range(0.0, 1e7));
  raw_pub_ = create_publisher<msgs::RawScan>("raw_scan");
  truth_pub_ = create_publisher<msgs::ScanTruth>("scan_truth");
}

void VirtualSensorNode::on_start() {
  if (scene_path_.empty()) throw bus::ParamError({}, "node '" + full_name() + "': parameter 'scene' is required");
  SystemOptions so;
  so.power_on_age_s = power_on_age_s_;
  system_ = SimulatedSystem::shared(scene_path_, so);
  sensor_ = sensor_name_.empty() ? 0 : system_->sensor_index(sensor_name_);
  if (system_->sensor_count() == 0) throw bus::ParamError({}, "node '" + full_name() + "': scene has no sensor");
  if (frame_id_.empty()) frame_id_ = system_->sensor_name(sensor_);
  const auto& p = system_->sensor(sensor_).params();
  // One tick per set: sets follow each other like the continuous raw mode.
  const double period = p.acquisition.raw_pulses.back() / p.emitter.pulse_rate_hz;
  timer_ = create_timer(std::chrono::nanoseconds(static_cast<std::int64_t>(period * 1e9)), [this] { tick(); });
}

void VirtualSensorNode::tick() {
  const double bus_t = now().seconds();
  const double shared = bus_t - system_->bus_epoch(bus_t);
  const auto& p = system_->sensor(sensor_).params();
  system_->set_emitting(sensor_, true, shared);
  const SensorSet set = system_->measure(sensor_, shared, p.acquisition.raw_pulses, index_++);
  const auto stamp = bus::Time::from_seconds(bus_t + (set.t_end_s - set.t_start_s)).to_msg();
  auto raw = std::make_unique<msgs::RawScan>();
  raw->header.stamp = stamp;
  raw->header.frame_id = frame_id_;
  to_msg(set, *raw);
  raw_pub_->publish(std::move(raw));
  if (publish_truth_) {
    auto t = std::make_unique<msgs::ScanTruth>();
    t->header.stamp = stamp;
    t->header.frame_id = frame_id_;
    system_->with_scene([&](const Scene& s) { to_msg(set, system_->sensor_name(sensor_), s.world, *t); });
    truth_pub_->publish(std::move(t));
  }
}

// ---------------------------------------------------------------------------- scene_truth

SceneTruthNode::SceneTruthNode(bus::NodeOptions o) : bus::Node(std::move(o)) {
  scene_path_ =
      declare_parameter<std::string>("scene", "", "scene YAML (sim/config/scenes/...) [required]", scene_file());
  frame_id_ = declare_parameter<std::string>("frame_id", "world", "the scene's world frame");
  rate_hz_ = declare_parameter("rate_hz", 10.0, "object poses per second", bus::ParamConstraints::range(0.01, 1000.0));
  scan_truth_ =
      declare_parameter("scan_truth", true, "publish the ScanTruth of the sets this process's virtual devices measure");
  objects_pub_ = create_publisher<msgs::SceneTruth>("objects");
  truth_pub_ = create_publisher<msgs::ScanTruth>("scan_truth", bus::QoS::keep_last(64));
}

SceneTruthNode::~SceneTruthNode() { on_stop(); }

void SceneTruthNode::on_start() {
  if (scene_path_.empty()) throw bus::ParamError({}, "node '" + full_name() + "': parameter 'scene' is required");
  system_ = SimulatedSystem::shared(scene_path_);
  if (scan_truth_) {
    // Called on a device's thread: queue, publish from this node's timer.
    observer_ = system_->add_observer([this](std::size_t sensor, const SensorSet& set) {
      std::lock_guard lock(mu_);
      if (pending_.size() < 256) pending_.emplace_back(sensor, set);
    });
    drain_timer_ = create_timer(std::chrono::milliseconds(5), [this] { drain(); });
  }
  objects_timer_ =
      create_timer(std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / rate_hz_)), [this] { publish_objects(); });
}

void SceneTruthNode::on_stop() {
  if (system_ && observer_ != 0) system_->remove_observer(observer_);
  observer_ = 0;
}

void SceneTruthNode::publish_objects() {
  auto m = std::make_unique<msgs::SceneTruth>();
  m->header.stamp = now().to_msg();
  m->header.frame_id = frame_id_;
  system_->with_scene([&](const Scene& s) { to_msg(s, *m); });
  objects_pub_->publish(std::move(m));
}

void SceneTruthNode::drain() {
  std::deque<std::pair<std::size_t, SensorSet>> sets;
  {
    std::lock_guard lock(mu_);
    sets.swap(pending_);
  }
  for (const auto& [sensor, set] : sets) {
    auto t = std::make_unique<msgs::ScanTruth>();
    // The set's end on the wall clock; with a sim clock, the node's time.
    const double end = system_->wall_time(set.t_end_s - system_->sensor_time(0.0));
    t->header.stamp = (clock().is_sim() ? now() : bus::Time::from_seconds(end)).to_msg();
    t->header.frame_id = system_->sensor_name(sensor);
    system_->with_scene([&](const Scene& s) { to_msg(set, system_->sensor_name(sensor), s.world, *t); });
    truth_pub_->publish(std::move(t));
  }
}

}  // namespace tinyline::sim::nodes

namespace tinyline::sim {

void nodes::register_scene_nodes(bus::NodeRegistry& r) {
  r.add<nodes::VirtualSensorNode>("sim", "virtual_sensor",
                                  "one simulated tiny TOF sensor of a scene on the bus clock: raw_scan + scan_truth");
  r.add<nodes::SceneTruthNode>("sim", "scene_truth",
                               "a scene's objects and the ground truth of its virtual devices' sets");
}

}  // namespace tinyline::sim
