// SPDX-License-Identifier: Apache-2.0
// Laser verification on simulated trusses (small N; the full run is the
// documented `tomato_eval --verify` command in docs/tomato_reasoning.md).
#include <gtest/gtest.h>
#include <optional>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/pipeline.hpp"
#include "tomato_reasoning/eval/variants.hpp"
#include "tomato_reasoning/eval/verification.hpp"

using namespace tinyline;
using namespace tinyline::tomato_reasoning;

namespace {

// The verification before the pedicel search: one scan where the loop
// starts, and the finder reading pedicels where the rail's calibration puts them.
eval::VerificationOptions before_search() {
  eval::VerificationOptions o;
  o.sweep = false;
  o.search_turns_deg.clear();
  o.pedicel_range_bias_m = 0.0;
  return o;
}

}  // namespace

TEST(LaserVerification, ConfirmsOrRelocatesThePedicelOfSimpleTrusses) {
  eval::VerificationOptions o;
  eval::VerificationHarness as_recognised(o);
  o.random_offset_m = 0.05;
  eval::VerificationHarness offset(o);
  int trials = 0, aligned = 0, offset_trials = 0, offset_aligned = 0, offset_vision = 0;
  for (std::uint64_t seed : {1u, 2u, 3u, 4u}) {
    const eval::Scenario s = eval::make_scenario(sim::TrussClass::kA, seed);
    PipelineParams p;
    p.gravity = s.gravity_camera;
    const PipelineResult r = TomatoPipeline(p).run(s.cloud());
    ASSERT_TRUE(r.status.ok()) << r.status.message;
    for (const auto& t : as_recognised.run(s, r)) {
      ++trials;
      aligned += t.on_pedicel;
      // A verdict of aligned is exactly "the throat ends on the true pedicel".
      EXPECT_EQ(t.verdict == eval::PickVerdict::kAligned, t.on_pedicel);
      if (t.on_pedicel) {
        EXPECT_LE(std::abs(t.lateral_error_m), 0.5 * o.scissor_opening_m);
      }
    }
    for (const auto& t : offset.run(s, r)) {
      ++offset_trials;
      offset_aligned += t.on_pedicel;
      offset_vision += t.vision_on_pedicel;
      EXPECT_LE(t.offset_m, 0.05);
    }
  }
  ASSERT_GE(trials, 4);
  EXPECT_GE(aligned, trials - 1);
  // Up to 5 cm off, vision alone rarely ends on the pedicel; the laser moves it there.
  EXPECT_GT(offset_aligned, offset_vision);
  EXPECT_GE(2 * offset_aligned, offset_trials);
}

TEST(LaserVerification, OptionsBySettingParseOrSayWhatIsWrong) {
  eval::VerificationOptions o;
  EXPECT_EQ(o.raw_pulses, (std::vector<int>{10, 20, 50, 120, 300}));  // realisable: pulse counts in tens
  eval::set_verification_option(o, "pulses", "3,8,25,80,250");
  EXPECT_EQ(o.raw_pulses, (std::vector<int>{3, 8, 25, 80, 250}));
  eval::set_verification_option(o, "max_move_m", "0.08");
  EXPECT_DOUBLE_EQ(o.pose.max_move_m, 0.08);
  eval::set_verification_option(o, "max_turn_deg", "0");
  EXPECT_DOUBLE_EQ(o.pose.max_turn_deg, 0.0);
  auto why = [&](const std::string& k, const std::string& v) {
    try {
      eval::set_verification_option(o, k, v);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(why("pulses", "10,x").find("not a number"), std::string::npos);
  EXPECT_NE(why("pulses", "10,,20").find("not a number"), std::string::npos);
  EXPECT_NE(why("pulses", "2.5").find("whole"), std::string::npos);
  EXPECT_NE(why("max_move_m", "-1").find("> 0"), std::string::npos);
  EXPECT_NE(why("max_turn_deg", "nan").find("not a number"), std::string::npos);
  EXPECT_NE(why("kappa", "1").find("unknown option"), std::string::npos);
}

// The closed loop of 4.5 (move, scan again, re-centre): on class B truss 204
// (a tuning seed) the first tomato's pick from a random offset ends on
// something else after the first scan's move alone, and on its pedicel once
// the hand scans again from there and re-centres. The case was found with
// the force model's pedicel direction alone: the seen pedicel's evidence
// moves the first scan elsewhere, so it is off here.
TEST(LaserVerification, TheClosedLoopEndsOnThePedicelWhereOneScanDoesNot) {
  eval::ScenarioOptions two_views;
  two_views.views = 2;
  const eval::Scenario s = eval::make_scenario(sim::TrussClass::kB, 204, two_views);
  PipelineParams force_model_only = eval::variant_params("default");
  force_model_only.pedicel.enabled = false;
  const PipelineResult r = eval::make_variant("default", force_model_only)->run(s);
  ASSERT_TRUE(r.status.ok()) << r.status.message;
  eval::VerificationOptions o = before_search();
  o.random_offset_m = 0.05;
  o.tomato_look = false;  // the loop alone
  eval::VerificationHarness one_scan(o);
  o.rescans = 2;
  eval::VerificationHarness loop(o);
  const auto first = one_scan.run(s, r), looped = loop.run(s, r);
  ASSERT_EQ(first.size(), looped.size());
  int rescued = -1;
  for (std::size_t i = 0; i < first.size(); ++i) {
    EXPECT_EQ(first[i].scans, 1);
    EXPECT_LE(looped[i].scans, 3);
    EXPECT_EQ(looped[i].truth, first[i].truth);
    if (first[i].truth == 0) rescued = static_cast<int>(i);
  }
  ASSERT_GE(rescued, 0) << "tomato 0 of truss B 204 is not picked";
  const auto& a = first[std::size_t(rescued)];
  const auto& b = looped[std::size_t(rescued)];
  EXPECT_EQ(a.verdict, eval::PickVerdict::kWrong) << a.reason;
  EXPECT_FALSE(a.on_pedicel);
  EXPECT_EQ(b.verdict, eval::PickVerdict::kAligned) << b.reason;
  EXPECT_TRUE(b.on_pedicel);
  EXPECT_GE(b.scans, 2);
}

namespace {

// A truss of the elastic-rod world (the evaluations'), two views, as tomato_eval sees it.
struct RodTruss {
  eval::Scenario s;
  PipelineResult r;
};

RodTruss rod_truss(sim::TrussClass c, std::uint64_t seed) {
  eval::ScenarioOptions so;
  so.views = 2;
  so.truss.physics = sim::TrussPhysics::kElasticRod;
  RodTruss t{eval::make_scenario(c, seed, so), {}};
  t.r = eval::make_variant("default", eval::variant_params("default"))->run(t.s);
  return t;
}

const eval::VerificationTrial* trial_of(const std::vector<eval::VerificationTrial>& trials, int truth) {
  for (const auto& t : trials)
    if (t.truth == truth) return &t;
  return nullptr;
}

/// The trial of true tomato `truth` on `t` under two settings, or nullopt
/// where a setting has none.
struct TwoTrials {
  std::optional<eval::VerificationTrial> before, after;
};
TwoTrials trials_of(const RodTruss& t, const eval::VerificationOptions& before, const eval::VerificationOptions& after,
                    int truth) {
  auto one = [&](const eval::VerificationOptions& o) -> std::optional<eval::VerificationTrial> {
    const auto trials = eval::VerificationHarness(o).run(t.s, t.r);
    const eval::VerificationTrial* found = trial_of(trials, truth);
    return found ? std::optional(*found) : std::nullopt;
  };
  return {one(before), one(after)};
}

}  // namespace

// The tomato look: from a random offset, the first pick of class A truss 206
// (a tuning seed) ends on another object with the closed loop alone, and on
// its pedicel once the fruit's section in a lowered scan has placed the
// truss (one more scan). Found by comparing the two on tuning seeds 201-230.
TEST(LaserVerification, TheTomatoLookPlacesTheTrussBeforeTheFirstMove) {
  const RodTruss t = rod_truss(sim::TrussClass::kA, 206);
  ASSERT_TRUE(t.r.status.ok()) << t.r.status.message;
  eval::VerificationOptions o = before_search();
  o.random_offset_m = 0.05;
  o.rescans = 2;
  o.tomato_look = false;
  eval::VerificationOptions with = o;
  with.tomato_look = true;
  const auto [before, after] = trials_of(t, o, with, 0);
  ASSERT_TRUE(before && after);
  EXPECT_NE(before->verdict, eval::PickVerdict::kAligned) << before->reason;
  EXPECT_FALSE(before->registered);
  EXPECT_TRUE(after->registered);
  EXPECT_EQ(after->verdict, eval::PickVerdict::kAligned) << after->reason;
  EXPECT_LE(after->scans, 1 + 1 + o.rescans);  // the look, the first scan, the re-scans
}

// A blind move (nothing pedicel-like where the registered truss puts the
// pedicel: go there and look) that sees nothing there either does not cut:
// the first pick of class B truss 210 (a tuning seed), from a random offset.
TEST(LaserVerification, ABlindMoveThatSeesNothingDoesNotCut) {
  const RodTruss t = rod_truss(sim::TrussClass::kB, 210);
  ASSERT_TRUE(t.r.status.ok()) << t.r.status.message;
  eval::VerificationOptions o = before_search();
  o.random_offset_m = 0.05;
  o.rescans = 2;
  o.look_nothing = eval::LookNothing::kBlindMove;
  eval::VerificationHarness harness(o);
  const auto trials = harness.run(t.s, t.r);
  const eval::VerificationTrial* first = trial_of(trials, 0);
  ASSERT_NE(first, nullptr);
  ASSERT_TRUE(first->registered);
  ASSERT_TRUE(first->blind_move);
  EXPECT_EQ(first->verdict, eval::PickVerdict::kNothingFound) << first->reason;
  EXPECT_FALSE(first->on_pedicel);
}

TEST(LaserVerification, TomatoLookOptionsParseOrSayWhatIsWrong) {
  eval::VerificationOptions o;
  EXPECT_TRUE(o.tomato_look);
  eval::set_verification_option(o, "tomato_look", "0");
  EXPECT_FALSE(o.tomato_look);
  eval::set_verification_option(o, "look_nothing", "2");
  EXPECT_EQ(o.look_nothing, eval::LookNothing::kUnregistered);
  eval::set_verification_option(o, "look_min_tomatoes", "2");
  EXPECT_EQ(o.look_min_tomatoes, 2);
  eval::set_verification_option(o, "registered_gate_sd", "3");
  EXPECT_DOUBLE_EQ(o.registered_gate_sd, 3.0);
  EXPECT_TRUE(o.look_heights_m.empty());
  eval::set_verification_option(o, "look_heights_m", "0.01,-0.01");
  EXPECT_EQ(o.look_heights_m, (std::vector<double>{0.01, -0.01}));
  EXPECT_THROW(eval::set_verification_option(o, "look_heights_m", "0.1"), std::invalid_argument);
  EXPECT_THROW(eval::set_verification_option(o, "tomato_look", "yes"), std::invalid_argument);
  EXPECT_THROW(eval::set_verification_option(o, "look_nothing", "3"), std::invalid_argument);
  EXPECT_THROW(eval::set_verification_option(o, "look_min_tomatoes", "0"), std::invalid_argument);
  EXPECT_THROW(eval::set_verification_option(o, "look_back_m", "-0.1"), std::invalid_argument);
}

// Scans at other heights along the expected pedicel (off by default: on the
// tuning trusses they added more wrong cuts than cuts on the pedicel): from
// the vision's own pose on class B truss 218 (a tuning seed) the first pick
// sees nothing pedicel-like where the registered truss puts the pedicel, and
// a plane 1 cm nearer the fruit sees it.
TEST(LaserVerification, AScanAtAnotherHeightFindsAPedicelTheCutHeightHides) {
  const RodTruss t = rod_truss(sim::TrussClass::kB, 218);
  ASSERT_TRUE(t.r.status.ok()) << t.r.status.message;
  eval::VerificationOptions one_height = before_search();
  one_height.rescans = 2;
  eval::VerificationOptions two_heights = one_height;
  two_heights.look_heights_m = {-0.01};
  const auto [before, after] = trials_of(t, one_height, two_heights, 0);
  ASSERT_TRUE(before && after);
  EXPECT_EQ(before->verdict, eval::PickVerdict::kNothingFound) << before->reason;
  EXPECT_EQ(after->verdict, eval::PickVerdict::kAligned) << after->reason;
}

// The pedicel search keeps looking where one scan sees nothing: from the
// vision's own pose, tomato 2 of class B truss 207 (a tuning seed) is not
// found by one scan, nor by the sweep from the robot's side; turned about
// the expected pedicel, the sweep finds it and the blades end on it.
TEST(LaserVerification, TheSearchTurnsToFindAPedicelHiddenFromTheFirstSide) {
  const RodTruss t = rod_truss(sim::TrussClass::kB, 207);
  ASSERT_TRUE(t.r.status.ok()) << t.r.status.message;
  eval::VerificationOptions before = before_search();
  before.rescans = 2;
  eval::VerificationOptions o;
  o.rescans = 2;
  const auto [one, swept] = trials_of(t, before, o, 2);
  ASSERT_TRUE(one && swept);
  EXPECT_EQ(one->verdict, eval::PickVerdict::kNothingFound) << one->reason;
  EXPECT_EQ(swept->verdict, eval::PickVerdict::kAligned) << swept->reason;
  // The look, the sweep's planes, a turned sweep at least, the re-scans.
  const int planes = static_cast<int>(o.search.heights_m.size());
  EXPECT_GT(swept->scans, 1 + planes + o.rescans);
  EXPECT_LE(swept->scans, 1 + planes * (1 + static_cast<int>(o.search_turns_deg.size())) + o.rescans + 1);
}

// The finder's thin-object range bias is measured on a rod when the harness
// is built: the hand laser reads a dark 6 mm rod farther than its axis.
TEST(LaserVerification, ThePedicelRangeBiasIsMeasuredOnARod) {
  eval::VerificationHarness measured{eval::VerificationOptions{}};
  EXPECT_GT(measured.pedicel_range_bias_m(), 0.002);
  EXPECT_LT(measured.pedicel_range_bias_m(), 0.03);
  EXPECT_NE(measured.describe().find("measured on a rod"), std::string::npos);
  eval::VerificationHarness set(before_search());
  EXPECT_EQ(set.pedicel_range_bias_m(), 0.0);
}

TEST(LaserVerification, SearchOptionsParseOrSayWhatIsWrong) {
  eval::VerificationOptions o;
  EXPECT_TRUE(o.sweep);
  eval::set_verification_option(o, "sweep", "0");
  EXPECT_FALSE(o.sweep);
  eval::set_verification_option(o, "sweep_heights_m", "0,0.01");
  EXPECT_EQ(o.search.heights_m, (std::vector<double>{0.0, 0.01}));
  eval::set_verification_option(o, "sweep_min_planes", "3");
  EXPECT_EQ(o.search.min_planes, 3);
  eval::set_verification_option(o, "search_turns_deg", "45,-45");
  EXPECT_EQ(o.search_turns_deg, (std::vector<double>{45.0, -45.0}));
  eval::set_verification_option(o, "search_turns_deg", "");
  EXPECT_TRUE(o.search_turns_deg.empty());
  eval::set_verification_option(o, "pedicel_range_bias_m", "0");
  EXPECT_EQ(o.pedicel_range_bias_m, 0.0);
  EXPECT_THROW(eval::set_verification_option(o, "sweep_heights_m", "0.01,0.02"), std::invalid_argument);
  EXPECT_THROW(eval::set_verification_option(o, "sweep_miss_factor", "0"), std::invalid_argument);
  EXPECT_THROW(eval::set_verification_option(o, "sweep_min_planes", "0"), std::invalid_argument);
  EXPECT_THROW(eval::set_verification_option(o, "search_turns_deg", "120"), std::invalid_argument);
  EXPECT_THROW(eval::set_verification_option(o, "pedicel_range_bias_m", "0.2"), std::invalid_argument);
}
