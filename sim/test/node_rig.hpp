// SPDX-License-Identifier: Apache-2.0
// The simulator's nodes' test rig: the nodes on stepped sim time with
// everything they publish kept (one file of tests per node includes it).
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include <tinyline/bus/testing.hpp>

#include "sim/nodes/nodes.hpp"
#include "sim/nodes/register.hpp"

namespace bus = tinyline::bus;
using namespace tinyline::sim;
using tinyline::tinyline_msgs::msg::RawScan;
using tinyline::tinyline_msgs::msg::ScanTruth;
using tinyline::tinyline_msgs::msg::SceneTruth;

namespace sim_node_test {

inline std::string scene_path() {
  return std::string(TINYLINE_SOURCE_DIR) + "/sim/config/scenes/calibration_rail.yaml";
}

// The sim nodes on stepped sim time from t = 100 s (bus/testing.hpp), with
// everything they publish kept.
struct Harness : bus::testing::NodeRig {
  Harness() : NodeRig({&register_nodes}, bus::Time::from_seconds(100.0)) {}
  std::vector<std::shared_ptr<const RawScan>>& raw = collect<RawScan>("raw_scan", bus::QoS::keep_last(100));
  std::vector<std::shared_ptr<const ScanTruth>>& truth = collect<ScanTruth>("scan_truth", bus::QoS::keep_last(100));
  std::vector<std::shared_ptr<const SceneTruth>>& objects = collect<SceneTruth>("objects", bus::QoS::keep_last(100));
  std::shared_ptr<bus::Node> add(const std::string& type, bus::NodeOptions o) {
    return NodeRig::add("sim", type, std::move(o));
  }
};

}  // namespace sim_node_test

using sim_node_test::Harness;
using sim_node_test::scene_path;
