// Each parameter described once: the tomato nodes declare every field of
// their settings from the settings' tables, with the structs' defaults.
#include <limits>
#include <map>
#include <string>
#include <variant>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bus/testing.hpp>

#include "tomato_reasoning/nodes/register.hpp"
#include "tomato_reasoning/param_tables.hpp"

namespace tr = tinyline::tomato_reasoning;
namespace bus = tinyline::bus;
namespace common = tinyline::common;
using ::testing::HasSubstr;

namespace {

// name -> default of every number or flag in `S`'s table.
template <class S>
std::map<std::string, double> table_defaults() {
  std::map<std::string, double> out;
  S s;
  for_each_param(s, [&out](auto& field, const common::Param& p, auto&&...) {
    using T = std::remove_cvref_t<decltype(field)>;
    if constexpr (std::is_arithmetic_v<T>) out[std::string(p.name)] = static_cast<double>(field);
  });
  return out;
}

double number(const bus::ParamValue& v) {
  if (const auto* d = std::get_if<double>(&v)) return *d;
  if (const auto* i = std::get_if<std::int64_t>(&v)) return static_cast<double>(*i);
  if (const auto* b = std::get_if<bool>(&v)) return *b ? 1.0 : 0.0;
  return std::numeric_limits<double>::quiet_NaN();
}

std::map<std::string, const bus::ParamDescriptor*> by_name(const bus::Node& n) {
  std::map<std::string, const bus::ParamDescriptor*> out;
  for (const auto& d : n.parameters()) out[d.name] = &d;
  return out;
}

}  // namespace

TEST(TomatoParamTables, EveryDefaultIsWithinItsTable) {
  EXPECT_TRUE(common::within_table(tr::PipelineParams{}).valid) << common::within_table(tr::PipelineParams{}).reason;
  EXPECT_TRUE(common::within_table(tr::PickPoseParams{}).valid);
}

TEST(TomatoParamTables, TheDetectorDeclaresEveryPipelineSettingWithItsDefault) {
  bus::testing::NodeRig rig({&tr::register_nodes});
  bus::NodeOptions o;
  o.name = "detector";
  o.param("smoothing.voxel_m", 0.005).param("spheres.hypothesis", std::string("four_points"));
  const auto node = rig.add("tomato_reasoning", "tomato_detector", o);
  auto declared = by_name(*node);
  const auto want = table_defaults<tr::PipelineParams>();
  ASSERT_EQ(want.size(), 45u);  // every field but the gravity vector and the hypothesis word
  for (const auto& [name, value] : want) {
    ASSERT_TRUE(declared.count(name)) << name << " is not a parameter";
    EXPECT_EQ(number(declared[name]->default_value), value) << name;
  }
  EXPECT_EQ(number(declared["smoothing.voxel_m"]->value), 0.005);
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
  auto declared = by_name(*node);
  for (const auto& [name, value] : table_defaults<tr::PickPoseParams>()) {
    ASSERT_TRUE(declared.count(name)) << name;
    EXPECT_EQ(number(declared[name]->default_value), value) << name;
  }
  EXPECT_EQ(std::get<std::vector<double>>(declared["approach_from"]->value), (std::vector<double>{0, 0, -1}));
}
