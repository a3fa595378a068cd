// SPDX-License-Identifier: Apache-2.0
// Each parameter described once: the settings' tables give the nodes their
// parameters (names, defaults, ranges), and every table field is settable.
#include <limits>
#include <map>
#include <string>
#include <variant>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bus/param_table_testing.hpp>
#include <tinyline/bus/testing.hpp>

#include "laser_clustering/nodes/register.hpp"
#include "laser_clustering/param_tables.hpp"

namespace lc = tinyline::laser_clustering;
namespace bus = tinyline::bus;
namespace common = tinyline::common;
using ::testing::HasSubstr;
using tinyline::bus::testing::param_number;
using tinyline::bus::testing::params_by_name;
using tinyline::bus::testing::table_defaults;

namespace {

std::shared_ptr<bus::Node> pedicel_finder(bus::testing::NodeRig& rig, bus::NodeOptions o, std::string name = "finder") {
  o.name = std::move(name);
  return rig.add("laser_clustering", "pedicel_finder", std::move(o));
}

}  // namespace

TEST(ParamTables, EveryDefaultIsWithinItsTable) {
  EXPECT_TRUE(common::within_table(lc::DbscanParams{}).ok());
  EXPECT_TRUE(common::within_table(lc::TwoStageParams{}).ok());
  EXPECT_TRUE(common::within_table(lc::PedicelFinderParams{}).ok());
  EXPECT_TRUE(common::within_table(lc::ReflectanceClusteringParams{}).ok());
  EXPECT_TRUE(common::within_table(lc::AlignmentParams{}).ok());
  EXPECT_TRUE(common::within_table(lc::SurfaceReflectanceParams{}).ok());
  EXPECT_TRUE(common::within_table(lc::TomatoRegistrationParams{}).ok());
}

TEST(ParamTables, AFieldOutsideItsTableIsNamedAsInLaunchFiles) {
  lc::TwoStageParams p;
  p.objects.eps = std::numeric_limits<double>::quiet_NaN();
  const auto v = common::within_table(p);
  ASSERT_FALSE(v.ok());
  EXPECT_THAT(v.message, HasSubstr("objects_eps_m must be in [1e-04, 2], got nan"));
  lc::PedicelFinderParams f;
  f.scissors.opening_m = 0.5;
  EXPECT_THAT(common::within_table(f).message, HasSubstr("scissor_opening_m must be in [0.001, 0.2], got 0.5"));
}

TEST(ParamTables, ThePedicelFinderDeclaresEveryFieldOfItsSettingsWithTheStructsDefault) {
  bus::testing::NodeRig rig({&lc::register_nodes});
  const auto node = pedicel_finder(rig, {});
  auto declared = params_by_name(*node);
  auto want = table_defaults<lc::PedicelFinderParams>();
  want.merge(table_defaults<lc::TwoStageParams>());
  ASSERT_EQ(want.size(), 30u);  // 15 + 3 scissor fields of the finder; 2 + 8 + 2 of the clustering
  for (const auto& [name, value] : want) {
    ASSERT_TRUE(declared.count(name)) << name << " is not a parameter";
    EXPECT_EQ(param_number(declared[name]->default_value), value) << name;
  }
  EXPECT_EQ(declared["scissor_opening_m"]->constraints.unit, "m");
  EXPECT_EQ(*declared["edge_reference_px"]->constraints.max, 16.0);
}

TEST(ParamTables, TheFinderSettingsALaunchFileCouldNotSetBeforeAreSettable) {
  bus::testing::NodeRig rig({&lc::register_nodes});
  bus::NodeOptions o;
  o.param("layout_miss_factor", 0.5).param("layout_extra_factor", 0.6);
  o.param("occlusion_margin_m", 0.03).param("recentre_sd_m", 0.02);
  const auto node = pedicel_finder(rig, o);
  std::map<std::string, double> value;
  for (const auto& d : node->parameters())
    value[d.name] = std::holds_alternative<double>(d.value) ? param_number(d.value) : 0;
  EXPECT_EQ(value["layout_miss_factor"], 0.5);
  EXPECT_EQ(value["layout_extra_factor"], 0.6);
  EXPECT_EQ(value["occlusion_margin_m"], 0.03);
  EXPECT_EQ(value["recentre_sd_m"], 0.02);
  bus::NodeOptions bad;
  bad.param("layout_miss_factor", 2.0);
  try {
    pedicel_finder(rig, bad, "finder2");
    FAIL() << "expected a ParamError";
  } catch (const bus::ParamError& e) {
    EXPECT_THAT(e.what(), HasSubstr("layout_miss_factor"));
  }
}

TEST(ParamTables, AWordParameterMapsToItsEnum) {
  bus::testing::NodeRig rig({&lc::register_nodes});
  bus::NodeOptions o;
  o.name = "align";
  o.param("surface_method", std::string("brightest_cluster"));
  const auto node = rig.add("laser_clustering", "alignment_search", o);
  int found = 0;
  for (const auto& d : node->parameters()) {
    if (d.name != "surface_method") continue;
    ++found;
    EXPECT_EQ(std::get<std::string>(d.default_value), "top_quantile");
    EXPECT_EQ(std::get<std::string>(d.value), "brightest_cluster");
    EXPECT_THAT(d.constraints.choices, ::testing::ElementsAre("top_quantile", "brightest_cluster"));
  }
  EXPECT_EQ(found, 1);
  bus::NodeOptions bad;
  bad.name = "align2";
  bad.param("surface_method", std::string("median"));
  EXPECT_THROW(rig.add("laser_clustering", "alignment_search", bad), bus::ParamError);
}
