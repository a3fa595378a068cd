// Each parameter described once: the hydrus nodes declare every field of
// their settings from the settings' tables, with the structs' defaults.
#include <limits>
#include <map>
#include <string>
#include <variant>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <tinyline/bus/testing.hpp>

#include "hydrus_fitting/nodes/register.hpp"
#include "hydrus_fitting/param_tables.hpp"

namespace hf = tinyline::hydrus_fitting;
namespace bus = tinyline::bus;
namespace common = tinyline::common;
using ::testing::HasSubstr;

namespace {

// name -> default of every number or flag in `S`'s table.
template <class S>
std::map<std::string, double> table_defaults(std::string_view prefix = {}) {
  std::map<std::string, double> out;
  S s;
  auto collect = [&out](auto& field, const common::Param& p, auto&&...) {
    using T = std::remove_cvref_t<decltype(field)>;
    if constexpr (std::is_arithmetic_v<T>) out[std::string(p.name)] = static_cast<double>(field);
  };
  common::nest(s, prefix, collect);
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

std::shared_ptr<bus::Node> add(bus::testing::NodeRig& rig, const std::string& type, bus::NodeOptions o) {
  o.name = type;
  o.param("robot_description", std::string("declared, not read before start"));
  return rig.add("hydrus_fitting", type, std::move(o));
}

}  // namespace

TEST(HydrusParamTables, EveryDefaultIsWithinItsTable) {
  EXPECT_TRUE(common::within_table(hf::CircleEstimatorParams{}).valid);
  EXPECT_TRUE(common::within_table(hf::SequencerParams{}).valid);
  EXPECT_TRUE(common::within_table(hf::JointBufferParams{}).valid);
  EXPECT_TRUE(common::within_table(hf::BasePoseBufferParams{}).valid);
}

TEST(HydrusParamTables, TheCircleFitterDeclaresEveryEstimatorSettingWithItsDefault) {
  bus::testing::NodeRig rig({&hf::register_nodes});
  const auto node = add(rig, "circle_fitter", {});
  auto declared = by_name(*node);
  auto want = table_defaults<hf::CircleEstimatorParams>();
  want.merge(table_defaults<hf::JointBufferParams>("joint_"));
  want.merge(table_defaults<hf::BasePoseBufferParams>("base_pose_"));
  // 11 of the robust fit, 5 + 11 of its refit, 2 of the fusion, 6 of the estimator, 2 + 2 of the buffers
  EXPECT_EQ(want.size(), 39u);
  for (const auto& [name, value] : want) {
    ASSERT_TRUE(declared.count(name)) << name << " is not a parameter";
    EXPECT_EQ(number(declared[name]->default_value), value) << name;
  }
  EXPECT_EQ(number(declared["known_radius_m"]->default_value), 0.0);  // unset
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
  auto declared = by_name(*node);
  for (const auto& [name, value] : table_defaults<hf::SequencerParams>()) {
    ASSERT_TRUE(declared.count(name)) << name << " is not a parameter";
    EXPECT_EQ(number(declared[name]->default_value), value) << name;
  }
  EXPECT_EQ(number(declared["joint_tolerance_s"]->default_value), 0.1);
  EXPECT_TRUE(declared.count("joint_history_s"));
}
