// SPDX-License-Identifier: Apache-2.0
// sequencer: the multi-sensor sequence mode of thesis 6.2.1 (Algorithm 4)
// as a node, scheduled by colouring the interference graph instead of
// time-slicing all n sensors.
//
//   joint_states  sensor_msgs/JointState   the robot's joints (sensor poses)
//   circle        tinyline_msgs/CircleFit  the object estimate: it occludes light (optional)
//   scans         tinyline_msgs/LineScan   every sensor's scans, to measure the achieved rate (optional)
//   laser_command tinyline_msgs/LaserCommand  published at every slot start: each sensor's
//                 laser on/off by name (`sensors`/`laser_on`) and the emitting sensors'
//                 description indices as `active_slots` (for drivers with sequence_slot = index)
//   diagnostics   diagnostic_msgs/DiagnosticArray  the schedule, its per-sensor rates beside
//                 the thesis's 1/n schedule, and the achieved rate per sensor
//
// mode: "colouring" (default), "time_slicing" (the thesis: one sensor per
// slot), or "all_on" (no sequencing: every laser always on; crosstalk).
//
// No sensor is trusted to obey: a sensor whose scans keep coming, read out
// well after it was told to stop emitting (`ignore_after` times), is taken
// as always emitting (firmware that ignores the command, as the published
// one does): it is put in every slot and reported in the diagnostics.
// The schedule is recomputed at each slot start from the joint angles at
// that time and the newest object estimate; when it changes, the cycle
// restarts at its first slot.
#pragma once

#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/diagnostic_msgs/diagnostic_array.hpp>
#include <tinyline/msg/sensor_msgs/joint_state.hpp>
#include <tinyline/msg/tinyline_msgs/circle_fit.hpp>
#include <tinyline/msg/tinyline_msgs/laser_command.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>

#include "hydrus_fitting/robot_model.hpp"
#include "hydrus_fitting/sequencer.hpp"

namespace tinyline::hydrus_fitting {

class SequencerNode : public bus::Node {
 public:
  explicit SequencerNode(bus::NodeOptions options);
  void on_start() override;

  [[nodiscard]] const Schedule& schedule() const { return schedule_; }
  [[nodiscard]] int slot() const { return slot_; }
  [[nodiscard]] std::uint64_t schedule_changes() const { return changes_; }

 private:
  void on_slot();
  void watch_scan(std::size_t sensor, bus::Time stamp);
  void publish_diagnostics();

  std::string description_path_;
  std::string mode_;
  double object_max_age_s_ = 0.0;
  double rate_window_s_ = 0.0;
  SequencerParams params_;
  JointBufferParams joint_params_;

  std::unique_ptr<RobotModel> model_;
  std::unique_ptr<JointStateBuffer> joints_;
  std::unique_ptr<Sequencer> sequencer_;
  Schedule schedule_;
  int slot_ = -1;
  std::uint64_t changes_ = 0;
  std::optional<std::pair<bus::Time, Circle>> object_;
  std::vector<std::deque<bus::Time>> arrivals_;  // per sensor, within the rate window
  int ignore_after_ = 3;
  std::vector<std::optional<bus::Time>> off_since_;  // per sensor: ordered off at (none: on)
  std::vector<int> scans_while_off_;                 // per sensor
  std::vector<int> always_on_;                       // sensors taken as always emitting
  std::string last_problem_;

  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::LaserCommand>> cmd_pub_;
  std::shared_ptr<bus::Publisher<diagnostic_msgs::msg::DiagnosticArray>> diag_pub_;
  std::shared_ptr<bus::Subscription<sensor_msgs::msg::JointState>> joint_sub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::CircleFit>> circle_sub_;
  std::shared_ptr<bus::Subscription<tinyline_msgs::msg::LineScan>> scan_sub_;
  std::shared_ptr<bus::Timer> slot_timer_, diag_timer_;
};

}  // namespace tinyline::hydrus_fitting
