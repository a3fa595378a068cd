// SPDX-License-Identifier: Apache-2.0
// Each parameter described once: the hydrus nodes declare every field of
// their settings from the settings' tables, with the structs' defaults.
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <variant>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bus/param_table_testing.hpp>
#include <tinyline/bus/testing.hpp>

#include "hydrus_fitting/nodes/register.hpp"
#include "hydrus_fitting/param_tables.hpp"

namespace hf = tinyline::hydrus_fitting;
namespace bus = tinyline::bus;
namespace common = tinyline::common;
using ::testing::HasSubstr;
using tinyline::bus::testing::param_number;
using tinyline::bus::testing::params_by_name;
using tinyline::bus::testing::table_defaults;

namespace {

std::shared_ptr<bus::Node> add(bus::testing::NodeRig& rig, const std::string& type, bus::NodeOptions o) {
  o.name = type;
  o.param("robot_description", std::string("declared, not read before start"));
  return rig.add("hydrus_fitting", type, std::move(o));
}

}  // namespace

TEST(HydrusParamTables, EveryDefaultIsWithinItsTable) {
  EXPECT_TRUE(common::within_table(hf::CircleEstimatorParams{}).ok());
  EXPECT_TRUE(common::within_table(hf::SequencerParams{}).ok());
  EXPECT_TRUE(common::within_table(hf::JointBufferParams{}).ok());
  EXPECT_TRUE(common::within_table(hf::BasePoseBufferParams{}).ok());
}

// The buffers' ranges live in their tables only: validate() is the table.
TEST(HydrusParamTables, TheBuffersAreBoundedByTheirTables) {
  EXPECT_THAT(hf::validate(hf::BasePoseBufferParams{.tolerance_s = 0.02, .history_s = 0.0}).message,
              HasSubstr("history_s must be in [0.01, 600], got 0"));
  EXPECT_THAT(hf::validate(hf::JointBufferParams{.tolerance_s = -1.0}).message,
              HasSubstr("tolerance_s must be in [0, 60], got -1"));
  EXPECT_THROW(hf::BasePoseBuffer({.tolerance_s = std::numeric_limits<double>::quiet_NaN()}), std::invalid_argument);
  hf::FusionParams f;
  f.self_filter_margin_m = -0.01;
  EXPECT_THAT(hf::validate(f).message, HasSubstr("self_filter_margin_m must be in [0, 1], got -0.01"));
}

TEST(HydrusParamTables, TheCircleFitterDeclaresEveryEstimatorSettingWithItsDefault) {
  bus::testing::NodeRig rig({&hf::register_nodes});
  const auto node = add(rig, "circle_fitter", {});
  auto declared = params_by_name(*node);
  auto want = table_defaults<hf::CircleEstimatorParams>();
  want.merge(table_defaults<hf::JointBufferParams>("joint_"));
  want.merge(table_defaults<hf::BasePoseBufferParams>("base_pose_"));
  // 11 of the robust fit, 5 + 11 of its refit, 2 of the fusion, 6 of the estimator, 2 + 2 of the buffers
  EXPECT_EQ(want.size(), 39u);
  for (const auto& [name, value] : want) {
    ASSERT_TRUE(declared.count(name)) << name << " is not a parameter";
    EXPECT_EQ(param_number(declared[name]->default_value), value) << name;
  }
  EXPECT_EQ(param_number(declared["known_radius_m"]->default_value), 0.0);  // unset
  EXPECT_EQ(std::get<bool>(declared["second_order_correction"]->default_value), true);
  EXPECT_EQ(std::get<std::vector<double>>(declared["range_noise_sd_m"]->default_value).size(), 10u);
}

TEST(HydrusParamTables, ANoiseModelOfUnpairedNumbersIsRefusedByName) {
  bus::testing::NodeRig rig({&hf::register_nodes});
  bus::NodeOptions o;
  o.param("range_noise_sd_m", std::vector<double>{0.2, 0.003, 0.5});
  try {
    add(rig, "circle_fitter", o);
    FAIL() << "expected a ParamError";
  } catch (const bus::ParamError& e) {
    EXPECT_THAT(e.what(), HasSubstr("range_noise_sd_m needs pairs of numbers"));
  }
}

TEST(HydrusParamTables, TheSequencerKeepsItsLooserJointToleranceAndDeclaresEverySetting) {
  bus::testing::NodeRig rig({&hf::register_nodes});
  const auto node = add(rig, "sequencer", {});
  auto declared = params_by_name(*node);
  for (const auto& [name, value] : table_defaults<hf::SequencerParams>()) {
    ASSERT_TRUE(declared.count(name)) << name << " is not a parameter";
    EXPECT_EQ(param_number(declared[name]->default_value), value) << name;
  }
  EXPECT_EQ(param_number(declared["joint_tolerance_s"]->default_value), 0.1);
  EXPECT_TRUE(declared.count("joint_history_s"));
}
