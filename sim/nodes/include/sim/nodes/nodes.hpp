// SPDX-License-Identifier: Apache-2.0
// Nodes of the simulator. Thin: they load a scene, call the core, convert.
//
// sim/virtual_sensor  runs one simulated sensor of a scene on the bus clock
//                     (no pty): publishes `raw_scan` (tinyline_msgs/RawScan,
//                     as the driver would) and `scan_truth` (ScanTruth) per
//                     set. With a sim clock and the deterministic executor it
//                     is fully reproducible: for tests and bag fixtures.
// sim/scene_truth     publishes the scene's objects (`objects`, SceneTruth)
//                     at rate_hz, and the ScanTruth of every set the virtual
//                     devices of this process measure for that scene
//                     (`scan_truth`), e.g. the driver's `port: sim:SCENE.yaml`.
#pragma once

#include <deque>
#include <memory>
#include <mutex>
#include <string>

#include <tinyline/bus/node.hpp>
#include <tinyline/msg/tinyline_msgs/raw_scan.hpp>
#include <tinyline/msg/tinyline_msgs/scan_truth.hpp>
#include <tinyline/msg/tinyline_msgs/scene_truth.hpp>

#include <sim/system.hpp>
#include <sim/yaml_node.hpp>

namespace tinyline::sim::nodes {

/// The constraints of a node's `scene` parameter: an input file, checked when
/// the node is built, so a launch (and `launch --check`) stops at the line
/// that set it. (Simulated nodes of other packages use it too.)
inline bus::ParamConstraints scene_file() { return bus::ParamConstraints::input_file(kMaxConfigFileBytes); }

/// SensorSet -> RawScan exactly as the wire carries it (charges x 10 as int16,
/// temperature as the MCU reads it).
void to_msg(const SensorSet& set, tinyline_msgs::msg::RawScan& out);
/// SensorSet -> ScanTruth; names come from the scene's world.
void to_msg(const SensorSet& set, const std::string& sensor, const World& world, tinyline_msgs::msg::ScanTruth& out);
void to_msg(const Scene& scene, tinyline_msgs::msg::SceneTruth& out);

class VirtualSensorNode : public bus::Node {
 public:
  explicit VirtualSensorNode(bus::NodeOptions options);
  void on_start() override;

 private:
  void tick();
  std::string scene_path_, sensor_name_, frame_id_;
  bool publish_truth_ = true;
  double power_on_age_s_ = 3600.0;
  std::shared_ptr<SimulatedSystem> system_;
  std::size_t sensor_ = 0;
  std::uint64_t index_ = 0;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::RawScan>> raw_pub_;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::ScanTruth>> truth_pub_;
  std::shared_ptr<bus::Timer> timer_;
};

class SceneTruthNode : public bus::Node {
 public:
  explicit SceneTruthNode(bus::NodeOptions options);
  ~SceneTruthNode() override;
  void on_start() override;
  void on_stop() override;

 private:
  void publish_objects();
  void drain();
  std::string scene_path_, frame_id_;
  double rate_hz_ = 10.0;
  bool scan_truth_ = true;
  std::shared_ptr<SimulatedSystem> system_;
  int observer_ = 0;
  std::mutex mu_;
  std::deque<std::pair<std::size_t, SensorSet>> pending_;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::SceneTruth>> objects_pub_;
  std::shared_ptr<bus::Publisher<tinyline_msgs::msg::ScanTruth>> truth_pub_;
  std::shared_ptr<bus::Timer> objects_timer_, drain_timer_;
};

}  // namespace tinyline::sim::nodes
