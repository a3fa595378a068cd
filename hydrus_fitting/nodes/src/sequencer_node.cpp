// SPDX-License-Identifier: Apache-2.0
#include "hydrus_fitting/nodes/sequencer_node.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include <tinyline/bus/param_table.hpp>

#include "hydrus_fitting/param_tables.hpp"

namespace tinyline::hydrus_fitting {

using bus::ParamConstraints;
namespace msgs = tinyline_msgs::msg;
namespace diag = diagnostic_msgs::msg;

SequencerNode::SequencerNode(bus::NodeOptions o) : Node(std::move(o)) {
  ParamConstraints required;
  required.required = true;
  description_path_ = declare_parameter<std::string>("robot_description", "",
                                                     "robot description YAML (links, joints, sensor mounts)", required);
  mode_ = declare_parameter<std::string>("mode", "colouring",
                                         "colouring | time_slicing (thesis, rate/n) | all_on (no sequencing)",
                                         ParamConstraints::one_of({"colouring", "time_slicing", "all_on"}));
  bus::declare_params(*this, params_);  // the tables: hydrus_fitting/param_tables.hpp
  object_max_age_s_ = declare_parameter("object_max_age_s", 0.5,
                                        "an object estimate older than this does not occlude [s]; 0: never use it",
                                        ParamConstraints::range(0.0, 3600.0));
  rate_window_s_ = declare_parameter("rate_window_s", 2.0, "window of the achieved-rate measurement [s]",
                                     ParamConstraints::range(0.1, 600.0));
  joint_params_.tolerance_s = 0.1;  // the schedule may use joint states this old: looser than a fit's
  bus::declare_params(*this, joint_params_, "joint_");
  const double diag_period =
      declare_parameter("diagnostics_period_s", 1.0, "[s]", ParamConstraints::range(0.01, 3600.0));
  ignore_after_ = declare_parameter("ignore_after", 3,
                                    "scans read out well after a sensor was told off before it is taken as always "
                                    "emitting (its firmware ignores the command)",
                                    ParamConstraints::range(1, 1000));

  cmd_pub_ = create_publisher<msgs::LaserCommand>("laser_command", bus::QoS::keep_last(10));
  diag_pub_ = create_publisher<diag::DiagnosticArray>("diagnostics");
  joint_sub_ = create_subscription<sensor_msgs::msg::JointState>(
      "joint_states", bus::QoS::keep_last(50), [this](const sensor_msgs::msg::JointState& m) {
        if (!joints_) return;
        const auto r = joints_->add(bus::Time::from_msg(m.header.stamp).ns, m.name, m.position);
        if (!r.reason.empty() && r.reason != last_problem_) {
          logger().warn("joint_states: {}", r.reason);
          last_problem_ = r.reason;
        }
      });
  circle_sub_ =
      create_subscription<msgs::CircleFit>("circle", bus::QoS::keep_last(5), [this](const msgs::CircleFit& m) {
        if (m.status != msgs::CircleFit::STATUS_OK) return;
        object_ = std::make_pair(bus::Time::from_msg(m.header.stamp), Circle{{m.centre.x, m.centre.y}, m.radius_m});
      });
  scan_sub_ = create_subscription<msgs::LineScan>("scans", bus::QoS::keep_last(20), [this](const msgs::LineScan& m) {
    if (!model_) return;
    const auto s = model_->sensor_index(m.header.frame_id);
    if (!s) return;
    auto& q = arrivals_[static_cast<std::size_t>(*s)];
    q.push_back(bus::Time::from_msg(m.header.stamp));
    watch_scan(static_cast<std::size_t>(*s), bus::Time::from_msg(m.header.stamp));
  });
  slot_timer_ = create_timer(bus::from_seconds(params_.timing.slot_s()), [this] { on_slot(); });
  diag_timer_ = create_timer(bus::from_seconds(diag_period), [this] { publish_diagnostics(); });
}

void SequencerNode::on_start() {
  model_ = std::make_unique<RobotModel>(RobotModel::load(description_path_));
  joints_ = std::make_unique<JointStateBuffer>(model_->joint_names(), joint_params_);
  sequencer_ = std::make_unique<Sequencer>(*model_, params_);
  arrivals_.assign(model_->sensors().size(), {});
  off_since_.assign(model_->sensors().size(), std::nullopt);
  scans_while_off_.assign(model_->sensors().size(), 0);
  const int n = static_cast<int>(model_->sensors().size());
  // Until joint states arrive the safe schedule is the thesis's.
  schedule_ = mode_ == "all_on"
                  ? Schedule{"all_on", {{}}, std::vector<double>(static_cast<std::size_t>(n), 0.0), params_.timing}
                  : time_slicing_schedule(n, params_.timing);
  if (mode_ == "all_on") {
    for (int i = 0; i < n; ++i) schedule_.slots[0].push_back(i);
    schedule_.rate_hz.assign(static_cast<std::size_t>(n), 1.0 / params_.timing.slot_s());
  }
  logger().info("robot '{}': {} sensors, mode {}, slot {:.1f} ms", model_->name(), n, mode_,
                1e3 * params_.timing.slot_s());
}

void SequencerNode::on_slot() {
  if (!model_) return;
  const int n = static_cast<int>(model_->sensors().size());
  if (mode_ == "colouring") {
    const JointLookup q = joints_->at(now().ns);
    if (q.ok()) {
      std::optional<Circle> object;
      if (object_ && object_max_age_s_ > 0.0 && bus::to_seconds(now() - object_->first) <= object_max_age_s_) {
        object = object_->second;
      }
      if (sequencer_->update(q.positions, object)) {
        schedule_ = sequencer_->schedule();
        slot_ = -1;  // a new cycle starts now
        ++changes_;
        logger().info("schedule: {} slots for {} sensors ({} conflicts)", schedule_.slot_count(), n,
                      sequencer_->graph().edges());
      }
      last_problem_.clear();
    } else if (q.status.message != last_problem_) {
      // Without the joints the geometry is unknown: fall back to one sensor per slot.
      logger().warn("{}: using one sensor per slot until joint states arrive", q.status.message);
      last_problem_ = q.status.message;
      schedule_ = time_slicing_schedule(n, params_.timing);
      slot_ = -1;
    }
  }
  const Schedule used = with_always_emitting(schedule_, always_on_);
  slot_ = (slot_ + 1) % std::max(1, used.slot_count());
  auto cmd = std::make_unique<msgs::LaserCommand>();
  cmd->header.stamp = now().to_msg();
  for (int i = 0; i < n; ++i) {
    const bool on = used.emits(slot_, i);
    auto& off = off_since_[static_cast<std::size_t>(i)];
    if (!on && !off) off = now();
    if (on) off.reset();
    cmd->sensors.push_back(model_->sensors()[static_cast<std::size_t>(i)].name);
    cmd->laser_on.push_back(on);
    if (on) cmd->active_slots.push_back(static_cast<std::uint16_t>(i));
  }
  cmd_pub_->publish(std::move(cmd));
}

void SequencerNode::watch_scan(std::size_t sensor, bus::Time stamp) {
  const auto& off = off_since_[sensor];
  if (!off || std::find(always_on_.begin(), always_on_.end(), static_cast<int>(sensor)) != always_on_.end()) return;
  // A set already under way when the order went out may still arrive; one
  // read out a whole set period after it was not asked for.
  if (bus::to_seconds(stamp - *off) <= params_.timing.set_period_s + params_.timing.guard_s) return;
  if (++scans_while_off_[sensor] < ignore_after_) return;
  always_on_.push_back(static_cast<int>(sensor));
  logger().warn("sensor '{}' keeps measuring while told to stop emitting ({} scans): taken as always emitting",
                model_->sensors()[sensor].name, scans_while_off_[sensor]);
}

void SequencerNode::publish_diagnostics() {
  if (!model_) return;
  const int n = static_cast<int>(model_->sensors().size());
  const Schedule thesis = time_slicing_schedule(n, params_.timing);
  auto arr = std::make_unique<diag::DiagnosticArray>();
  arr->header.stamp = now().to_msg();
  diag::DiagnosticStatus st;
  st.name = fmt::format("{}: schedule", full_name());
  st.hardware_id = model_->name();
  st.level = diag::DiagnosticStatus::OK;
  st.message = fmt::format("{} ({} slots of {:.1f} ms for {} sensors)", schedule_.name, schedule_.slot_count(),
                           1e3 * params_.timing.slot_s(), n);
  auto kv = [&](std::string k, std::string v) {
    diag::KeyValue x;
    x.key = std::move(k);
    x.value = std::move(v);
    st.values.push_back(std::move(x));
  };
  std::string slots;
  for (const auto& s : schedule_.slots) {
    std::string names;
    for (const int i : s) names += (names.empty() ? "" : "+") + model_->sensors()[static_cast<std::size_t>(i)].name;
    slots += (slots.empty() ? "" : " | ") + names;
  }
  kv("slots", slots);
  if (sequencer_ && mode_ == "colouring") kv("conflicts", std::to_string(sequencer_->graph().edges()));
  kv("schedule_changes", std::to_string(changes_));
  const bus::Time t = now();
  for (int i = 0; i < n; ++i) {
    auto& q = arrivals_[static_cast<std::size_t>(i)];
    while (!q.empty() && bus::to_seconds(t - q.front()) > rate_window_s_) q.pop_front();
    const auto& name = model_->sensors()[static_cast<std::size_t>(i)].name;
    kv(name + ".rate_hz", fmt::format("{:.2f}", schedule_.rate_hz[static_cast<std::size_t>(i)]));
    kv(name + ".thesis_rate_hz", fmt::format("{:.2f}", thesis.rate_hz[static_cast<std::size_t>(i)]));
    kv(name + ".achieved_hz", fmt::format("{:.2f}", static_cast<double>(q.size()) / rate_window_s_));
    const bool always = std::find(always_on_.begin(), always_on_.end(), i) != always_on_.end();
    kv(name + ".obeys_laser_off",
       always ? fmt::format("no ({} scans while off): always emitting", scans_while_off_[static_cast<std::size_t>(i)])
              : "yes or untested");
  }
  arr->status.push_back(std::move(st));
  diag_pub_->publish(std::move(arr));
}

}  // namespace tinyline::hydrus_fitting
