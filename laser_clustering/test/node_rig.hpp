// SPDX-License-Identifier: Apache-2.0
// The laser_clustering nodes' test rig: the nodes on stepped sim time,
// scans as messages, and the synthetic scenes the node tests share (one
// file of tests per node includes it).
#pragma once

#include <cmath>
#include <functional>
#include <limits>
#include <numbers>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bus/testing.hpp>

#include "laser_clustering/nodes/conversions.hpp"
#include "laser_clustering/nodes/nodes.hpp"
#include "laser_clustering/nodes/register.hpp"
#include "laser_clustering/tomato_registration.hpp"
#include "synthetic_scan.hpp"

namespace lc = tinyline::laser_clustering;
namespace bus = tinyline::bus;
using ::testing::HasSubstr;
using tinyline::geometry_msgs::msg::PointStamped;
using tinyline::sensor_msgs::msg::JointState;
using tinyline::tinyline_msgs::msg::AlignmentResult;
using tinyline::tinyline_msgs::msg::ExpectedTomatoes;
using tinyline::tinyline_msgs::msg::LineClusters;
using tinyline::tinyline_msgs::msg::LineScan;
using tinyline::tinyline_msgs::msg::PedicelDetection;
using tinyline::tinyline_msgs::msg::PedicelLayout;
using tinyline::tinyline_msgs::msg::TrussRegistration;

namespace lc_node_test {

// The laser_clustering nodes on stepped sim time (bus/testing.hpp); `io`
// publishes inputs and receives outputs.
struct Harness : bus::testing::NodeRig {
  Harness() : NodeRig({&lc::register_nodes}) {}
  std::shared_ptr<bus::Node> add(const std::string& type, bus::NodeOptions o) {
    return NodeRig::add("laser_clustering", type, std::move(o));
  }
  /// The pedicel finder as most tests run it: the blade throat 12 cm ahead.
  void add_finder() {
    bus::NodeOptions o;
    o.name = "finder";
    o.param("scissor_centre_z_m", 0.12);
    add("pedicel_finder", o);
  }
};

inline std::unique_ptr<LineScan> to_msg(const lc::LineScan& s, double t_s) {
  auto m = std::make_unique<LineScan>();
  m->header.stamp = bus::Time::from_seconds(t_s).to_msg();
  m->header.frame_id = "laser";
  for (std::size_t i = 0; i < s.size(); ++i) {
    m->angles.push_back(static_cast<float>(s.angle_rad[i]));
    const bool valid = s.valid(i);
    m->distance_m.push_back(valid ? static_cast<float>(s.range_m[i]) : std::nanf(""));
    m->status.push_back(valid ? LineScan::STATUS_VALID : LineScan::STATUS_TOO_DARK);
    if (!s.reflectance.empty()) m->reflectance.push_back(static_cast<float>(s.reflectance[i]));
  }
  return m;
}

// Discs before a wall 40 cm away.
inline lc::test::SynthScan before_wall(const std::vector<lc::test::Disc>& discs, unsigned seed = 1) {
  lc::test::SynthParams sp;
  sp.wall_z_m = 0.40;
  sp.seed = seed;
  return lc::test::synth_scan(discs, sp);
}

inline lc::test::SynthScan pedicel_scene(double x, unsigned seed = 1) {
  return before_wall({{x, 0.13, 0.003, 6.0, 1}, {-0.08, 0.25, 0.03, 6.0, 2}}, seed);
}

// What the node's scan conversion gives the core (float on the wire).
inline lc::LineScan through_the_wire(const lc::LineScan& s) {
  lc::LineScan out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    out.angle_rad.push_back(static_cast<float>(s.angle_rad[i]));
    out.range_m.push_back(s.valid(i) ? static_cast<double>(static_cast<float>(s.range_m[i]))
                                     : std::numeric_limits<double>::quiet_NaN());
    if (!s.reflectance.empty()) {
      out.reflectance.push_back(s.valid(i) ? static_cast<double>(static_cast<float>(s.reflectance[i]))
                                           : std::numeric_limits<double>::quiet_NaN());
    }
  }
  return out;
}

inline lc::LineScan stick_scan(double pitch, double best_pitch, unsigned seed) {
  lc::test::SynthParams sp;
  sp.wall_z_m = 0.30;
  sp.wall_reflectance = 4.8;
  sp.noise_sd_m = 0.003;
  sp.seed = seed;
  const double lobe = 5.0 + 32.0 * std::exp(-0.5 * std::pow((pitch - best_pitch) / 0.07, 2));
  return lc::test::synth_scan({{0.0, 0.30 - 0.004 + 0.005, 0.005, lobe, 1}}, sp).scan;
}

}  // namespace lc_node_test

using lc_node_test::before_wall;
using lc_node_test::Harness;
using lc_node_test::pedicel_scene;
using lc_node_test::stick_scan;
using lc_node_test::through_the_wire;
using lc_node_test::to_msg;
