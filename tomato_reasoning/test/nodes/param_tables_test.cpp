// SPDX-License-Identifier: Apache-2.0
// Each parameter described once: the tomato nodes declare every field of
// their settings from the settings' tables, with the structs' defaults.
#include <limits>
#include <map>
#include <string>
#include <variant>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bus/param_table_testing.hpp>
#include <tinyline/bus/testing.hpp>

#include "tomato_reasoning/nodes/register.hpp"
#include "tomato_reasoning/param_tables.hpp"

namespace tr = tinyline::tomato_reasoning;
namespace bus = tinyline::bus;
namespace common = tinyline::common;
using ::testing::HasSubstr;
using tinyline::bus::testing::param_number;
using tinyline::bus::testing::params_by_name;
using tinyline::bus::testing::table_defaults;

namespace {}  // namespace

TEST(TomatoParamTables, EveryDefaultIsWithinItsTable) {
  EXPECT_TRUE(common::within_table(tr::PipelineParams{}).ok()) << common::within_table(tr::PipelineParams{}).message;
  EXPECT_TRUE(common::within_table(tr::PickPoseParams{}).ok());
}

// A single field's range lives in its table; validate() adds only the rules
// that span fields.
TEST(TomatoParamTables, ValidateChecksTheTablesRangesAndTheRulesAcrossFields) {
  tr::SmoothingParams sm;
  sm.polynomial_order = 3;
  EXPECT_THAT(tr::validate(sm).message, HasSubstr("polynomial_order must be in [1, 2], got 3"));
  tr::SphereRansacParams sp;
  sp.confidence = 1.0;
  EXPECT_THAT(tr::validate(sp).message, HasSubstr("confidence must be in [0.5, 0.999999], got 1"));
  sp = {};
  sp.radius_min_m = 0.05;
  sp.radius_max_m = 0.04;
  EXPECT_THAT(tr::validate(sp).message, HasSubstr("radius_min_m <= radius_max_m"));
  tr::BranchClusteringParams b;
  b.tolerance_m = 0.0;
  EXPECT_THAT(tr::validate(b).message, HasSubstr("tolerance_m must be in [0.001, 1], got 0"));
  b = {};
  b.min_range_m = b.max_range_m;
  EXPECT_THAT(tr::validate(b).message, HasSubstr("min_range_m < max_range_m"));
  tr::HsiFilterParams h;
  h.s_min = 300;
  EXPECT_THAT(tr::validate(h).message, HasSubstr("s_min must be in [0, 255], got 300"));
  h = {};
  h.i_min = h.i_max + 1;
  EXPECT_THAT(tr::validate(h).message, HasSubstr("i_min <= i_max"));
  tr::NoiseBiasParams nb;
  nb.band_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(tr::validate(nb).message, HasSubstr("band_m must be in [1e-04, 0.1], got nan"));
  tr::ForceModelParams f;
  f.samples = 5;
  EXPECT_THAT(tr::validate(f).message, HasSubstr("samples must be in [10, 1e+05], got 5"));
  tr::PipelineParams p;
  p.cut.candidates = 0;
  EXPECT_THAT(tr::validate(p).message, HasSubstr("cut: candidates must be in [1, 1e+05], got 0"));
}

TEST(TomatoParamTables, TheDetectorDeclaresEveryPipelineSettingWithItsDefault) {
  bus::testing::NodeRig rig({&tr::register_nodes});
  bus::NodeOptions o;
  o.name = "detector";
  o.param("smoothing.voxel_m", 0.005).param("spheres.hypothesis", std::string("four_points"));
  const auto node = rig.add("tomato_reasoning", "tomato_detector", o);
  auto declared = params_by_name(*node);
  const auto want = table_defaults<tr::PipelineParams>();
  ASSERT_EQ(want.size(), 71u);  // every field but the gravity vector and the hypothesis word
  for (const auto& [name, value] : want) {
    ASSERT_TRUE(declared.count(name)) << name << " is not a parameter";
    EXPECT_EQ(param_number(declared[name]->default_value), value) << name;
  }
  EXPECT_EQ(param_number(declared["smoothing.voxel_m"]->value), 0.005);
  EXPECT_EQ(std::get<std::string>(declared["spheres.hypothesis"]->value), "four_points");
  EXPECT_EQ(std::get<std::vector<double>>(declared["gravity"]->default_value), (std::vector<double>{0, 1, 0}));
}

TEST(TomatoParamTables, AGravityOfTheWrongSizeOrZeroIsRefusedByName) {
  bus::testing::NodeRig rig({&tr::register_nodes});
  bus::NodeOptions two;
  two.name = "d1";
  two.param("gravity", std::vector<double>{0.0, 1.0});
  try {
    rig.add("tomato_reasoning", "tomato_detector", two);
    FAIL() << "expected a ParamError";
  } catch (const bus::ParamError& e) {
    EXPECT_THAT(e.what(), HasSubstr("gravity needs 3 numbers, got 2"));
  }
  bus::NodeOptions zero;
  zero.name = "d2";
  zero.param("gravity", std::vector<double>{0.0, 0.0, 0.0});
  EXPECT_THROW(rig.add("tomato_reasoning", "tomato_detector", zero), bus::ParamError);
}

TEST(TomatoParamTables, ThePickVerifierDeclaresWhereTheRobotComesFrom) {
  bus::testing::NodeRig rig({&tr::register_nodes});
  bus::NodeOptions o;
  o.name = "verifier";
  o.param("approach_from", std::vector<double>{0.0, 0.0, -1.0});
  const auto node = rig.add("tomato_reasoning", "pick_verifier", o);
  auto declared = params_by_name(*node);
  for (const auto& [name, value] : table_defaults<tr::PickPoseParams>()) {
    ASSERT_TRUE(declared.count(name)) << name;
    EXPECT_EQ(param_number(declared[name]->default_value), value) << name;
  }
  EXPECT_EQ(std::get<std::vector<double>>(declared["approach_from"]->value), (std::vector<double>{0, 0, -1}));
}
