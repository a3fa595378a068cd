// SPDX-License-Identifier: Apache-2.0
// Harvest trials (Table 4.2 protocol, eval/harvest.hpp) on simulated
// trusses: the counts, with the blades scripted where a test needs an
// outcome, and with sim's cutter model.
#include <cmath>
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <vector>

#include "tomato_reasoning/eval/harvest.hpp"
#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/eval/variants.hpp"
#include "tomato_reasoning/eval/verification.hpp"

using namespace tinyline;
using namespace tinyline::tomato_reasoning;

namespace {

struct Harvested {
  eval::Scenario scenario;
  PipelineResult result;
};

Harvested scene(sim::TrussClass c, std::uint64_t seed) {
  Harvested h{eval::make_scenario(c, seed), {}};
  h.result = eval::make_variant("default", eval::variant_params("default"))->run(h.scenario);
  return h;
}

eval::VerificationHarness& laser() {
  static eval::VerificationHarness h([] {
    eval::VerificationOptions o;
    o.rescans = 2;
    return eval::harvest_laser(o, {});
  }());
  return h;
}

// The harvest's hand laser leaves the rod-measured range bias out unless
// asked (on tuning trusses it added jams), and keeps a bias the caller set.
TEST(HarvestTrials, TheHarvestsLaserLeavesTheRodBiasOutUnlessAsked) {
  eval::VerificationOptions measured;  // NaN: measure on the rod
  EXPECT_EQ(eval::harvest_laser(measured, {}).pedicel_range_bias_m, 0.0);
  eval::HarvestOptions asked;
  eval::set_harvest_option(asked, "rod_range_bias", "1");
  EXPECT_TRUE(std::isnan(eval::harvest_laser(measured, asked).pedicel_range_bias_m));
  eval::VerificationOptions set = measured;
  set.pedicel_range_bias_m = 0.004;
  EXPECT_EQ(eval::harvest_laser(set, {}).pedicel_range_bias_m, 0.004);
  EXPECT_EQ(laser().pedicel_range_bias_m(), 0.0);
}

eval::HarvestCounts count(const std::vector<eval::HarvestTrial>& trials) {
  eval::HarvestCounts c;
  for (const auto& t : trials) c.add(t);
  return c;
}

}  // namespace

// The first closing misses (the scripted blades close 3 cm to the side of
// where the hand is), the second, after the laser's re-scan from there, cuts
// with the real cutter: every pick is SP(2), none SP(1).
TEST(HarvestTrials, AMissedFirstCutIsPickedOnTheSecondAttempt) {
  const Harvested h = scene(sim::TrussClass::kA, 1);
  ASSERT_TRUE(h.result.status.ok()) << h.result.status.message;
  std::map<int, int> calls;
  const eval::CutModel first_misses = [&](const sim::Truss& truss, const Eigen::Isometry3d& T, int target) {
    const Eigen::Isometry3d aside = ++calls[target] == 1 ? T * Eigen::Translation3d(0.03, 0, 0) : T;
    return sim::close_blades(truss, aside, sim::BladeParams{}, target);
  };
  const auto trials = eval::harvest(laser(), h.scenario, h.result, {}, first_misses);
  const eval::HarvestCounts c = count(trials);
  ASSERT_GE(c.detected, 1);
  EXPECT_EQ(c.picked_first, 0);
  EXPECT_GE(c.picked_second, 1);
  for (const auto& t : trials) {
    if (t.outcome != eval::HarvestOutcome::kPickedSecond) continue;
    EXPECT_EQ(t.attempts, 2);
    EXPECT_EQ(t.cuts, "closed_on_nothing;cut_target");
  }
  // The same truss with the real blades throughout: picked on the first attempt.
  const eval::HarvestCounts real = count(eval::harvest(laser(), h.scenario, h.result));
  EXPECT_EQ(real.picked_first, c.picked_second);
  EXPECT_EQ(real.picked_second, 0);
}

// Blades that jam (on the peduncle) end each attempted trial as a cut
// failure at the first closing (no second attempt after it); the harvest
// goes on to the next tomato.
TEST(HarvestTrials, AJammedCutIsACutFailure) {
  const Harvested h = scene(sim::TrussClass::kB, 2);
  ASSERT_TRUE(h.result.status.ok()) << h.result.status.message;
  const eval::CutModel jams = [](const sim::Truss&, const Eigen::Isometry3d&, int) {
    sim::CutOutcome o;
    o.result = sim::CutResult::kJammed;
    o.object = "peduncle";
    return o;
  };
  eval::HarvestOptions no_checks;  // the blades close wherever the laser put them: the scripted jam decides
  no_checks.check_blades = false;
  const auto trials = eval::harvest(laser(), h.scenario, h.result, no_checks, jams);
  const eval::HarvestCounts c = count(trials);
  EXPECT_EQ(c.picked_first + c.picked_second, 0);
  ASSERT_GE(c.cut_failures, 2);
  for (const auto& t : trials) {
    if (t.outcome != eval::HarvestOutcome::kCutFailure) continue;
    // One closing, the last thing tried: a first attempt the verification refused may come before it.
    EXPECT_TRUE(t.cuts == "jammed" || t.cuts == "no_cut;jammed") << t.cuts;
    EXPECT_EQ(t.attempts, t.cuts == "jammed" ? 1 : 2);
    EXPECT_EQ(t.jammed_on, "peduncle");
  }
}

// A cut of another tomato's pedicel drops that fruit (knocked off, never
// attempted) and the target gets its second attempt.
TEST(HarvestTrials, ANeighboursPedicelCutKnocksItsFruitOff) {
  const Harvested h = scene(sim::TrussClass::kB, 2);
  ASSERT_TRUE(h.result.status.ok()) << h.result.status.message;
  ASSERT_GE(h.scenario.truss.tomatoes.size(), 3u);
  int first_target = -1, victim = -1;
  const eval::CutModel wrong_first = [&](const sim::Truss& truss, const Eigen::Isometry3d& T, int target) {
    if (first_target < 0) {
      first_target = target;
      // The last tomato of the truss hangs; sever its pedicel instead.
      victim = static_cast<int>(truss.tomatoes.size()) - 1 == target ? 0 : static_cast<int>(truss.tomatoes.size()) - 1;
      sim::CutOutcome o;
      o.result = sim::CutResult::kCutOtherPedicel;
      o.tomato = victim;
      o.severed = {victim};
      return o;
    }
    return sim::close_blades(truss, T, sim::BladeParams{}, target);
  };
  const auto trials = eval::harvest(laser(), h.scenario, h.result, {}, wrong_first);
  ASSERT_GE(first_target, 0);
  const auto& victim_trial = trials[std::size_t(victim)];
  EXPECT_EQ(victim_trial.outcome, eval::HarvestOutcome::kKnockedOff);
  EXPECT_EQ(victim_trial.attempts, 0);
  const auto& target_trial = trials[std::size_t(first_target)];
  EXPECT_EQ(target_trial.cuts.rfind("cut_other_pedicel;", 0), 0u) << target_trial.cuts;
  EXPECT_EQ(target_trial.attempts, 2);
}

std::vector<std::string> attempts_of(const std::string& cuts) {
  std::vector<std::string> out;
  std::size_t from = 0;
  while (!cuts.empty() && from <= cuts.size()) {
    const std::size_t semi = std::min(cuts.find(';', from), cuts.size());
    out.push_back(cuts.substr(from, semi - from));
    from = semi + 1;
  }
  return out;
}

// The outcome a trial's record implies: each attempt's end in `cuts` (one
// per attempt). A trial never attempted was knocked off only when some
// attempt in its truss severed another's pedicel (`others_severed`).
eval::HarvestOutcome implied(const eval::HarvestTrial& t, int others_severed) {
  const std::vector<std::string> ends = attempts_of(t.cuts);
  if (ends.empty())
    return t.outcome == eval::HarvestOutcome::kKnockedOff && others_severed > 0 ? eval::HarvestOutcome::kKnockedOff
                                                                                : eval::HarvestOutcome::kLeftForHuman;
  if (ends.back() == "cut_target")
    return ends.size() == 1 ? eval::HarvestOutcome::kPickedFirst : eval::HarvestOutcome::kPickedSecond;
  if (ends.back() == "jammed") return eval::HarvestOutcome::kCutFailure;
  return eval::HarvestOutcome::kLeftForHuman;
}

int severed_others(const std::vector<eval::HarvestTrial>& trials) {
  int n = 0;
  for (const auto& t : trials)
    for (const auto& end : attempts_of(t.cuts)) n += end == "cut_other_pedicel";
  return n;
}

// With the real cutter, on classes A-C: one trial per true tomato; every
// trial's outcome is the one its record of attempts implies (one end per
// attempt, a jam names what jammed, an undetected fruit is left for a human
// unattempted, a knocked-off one was never attempted), so the counts,
// recounted from the records, match Table 4.2's row exactly; and class A
// trusses are mostly picked on the first attempt.
TEST(HarvestTrials, CountsPartitionTheTrials) {
  eval::HarvestCounts all, class_a;
  std::map<eval::HarvestOutcome, int> recounted;
  for (sim::TrussClass c : {sim::TrussClass::kA, sim::TrussClass::kB, sim::TrussClass::kC}) {
    for (std::uint64_t seed : {1u, 2u}) {
      const Harvested h = scene(c, seed);
      ASSERT_TRUE(h.result.status.ok()) << h.result.status.message;
      const auto trials = eval::harvest(laser(), h.scenario, h.result);
      ASSERT_EQ(trials.size(), h.scenario.truss.tomatoes.size());
      const int severed = severed_others(trials);
      for (const auto& t : trials) {
        SCOPED_TRACE(std::string(1, t.complexity) + " seed " + std::to_string(seed) + " tomato " +
                     std::to_string(t.truth) + ": " + t.cuts + " / " + t.why);
        EXPECT_EQ(t.outcome, implied(t, severed));
        if (!t.detected) {
          EXPECT_EQ(t.attempts, 0);
        }
        if (t.attempts > 0) {
          EXPECT_EQ(attempts_of(t.cuts).size(), static_cast<std::size_t>(t.attempts));
        }
        EXPECT_LE(t.attempts, 2);
        EXPECT_EQ(t.outcome == eval::HarvestOutcome::kCutFailure, !t.jammed_on.empty());
        if (t.outcome == eval::HarvestOutcome::kKnockedOff) {
          EXPECT_EQ(t.attempts, 0);
        }
        recounted[implied(t, severed)]++;
      }
      EXPECT_LE(count(trials).knocked_off, severed);
      all += count(trials);
      if (c == sim::TrussClass::kA) class_a += count(trials);
    }
  }
  EXPECT_EQ(all.picked_first, recounted[eval::HarvestOutcome::kPickedFirst]);
  EXPECT_EQ(all.picked_second, recounted[eval::HarvestOutcome::kPickedSecond]);
  EXPECT_EQ(all.cut_failures, recounted[eval::HarvestOutcome::kCutFailure]);
  EXPECT_EQ(all.knocked_off, recounted[eval::HarvestOutcome::kKnockedOff]);
  EXPECT_EQ(all.left_for_human, recounted[eval::HarvestOutcome::kLeftForHuman]);
  EXPECT_GE(2 * class_a.picked_first, class_a.trials);
}

TEST(HarvestTrials, OptionsBySettingParseOrSayWhatIsWrong) {
  eval::HarvestOptions o;
  eval::set_harvest_option(o, "attempts", "3");
  EXPECT_EQ(o.attempts, 3);
  EXPECT_TRUE(o.later_attempts_approach_far);
  eval::set_harvest_option(o, "later_attempts_approach_far", "0");
  EXPECT_FALSE(o.later_attempts_approach_far);
  eval::set_harvest_option(o, "ceiling", "1");
  EXPECT_TRUE(o.ceiling);
  auto why = [&](const std::string& k, const std::string& v) {
    try {
      eval::set_harvest_option(o, k, v);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(why("attempts", "0").find("whole number"), std::string::npos);
  EXPECT_NE(why("attempts", "2.5").find("whole number"), std::string::npos);
  EXPECT_NE(why("later_attempts_approach_far", "yes").find("0 or 1"), std::string::npos);
  EXPECT_NE(why("blades", "1").find("unknown option"), std::string::npos);
  eval::set_harvest_option(o, "probes", "0");
  EXPECT_EQ(o.probes, 0);
  eval::set_harvest_option(o, "probe_shifts_mm", "0,-3,4.5");
  ASSERT_EQ(o.probe.shifts_m.size(), 3u);
  EXPECT_DOUBLE_EQ(o.probe.shifts_m[2], 0.0045);
  eval::set_harvest_option(o, "probe_rolls_deg", "0,20");
  EXPECT_EQ(o.probe.rolls_deg, (std::vector<double>{0.0, 20.0}));
  EXPECT_TRUE(o.probe_after_laser_refusal);
  eval::set_harvest_option(o, "probe_after_laser_refusal", "0");
  EXPECT_FALSE(o.probe_after_laser_refusal);
  EXPECT_EQ(o.blade_plane_shifts_m, (std::vector<double>{-0.002, 0.002}));
  eval::set_harvest_option(o, "blade_plane_shifts_mm", "-1.5,3");
  EXPECT_EQ(o.blade_plane_shifts_m, (std::vector<double>{-0.0015, 0.003}));
  eval::set_harvest_option(o, "blade_plane_shifts_mm", "none");
  EXPECT_TRUE(o.blade_plane_shifts_m.empty());
  EXPECT_LT(o.arbitrate_mm, 0.0);
  eval::set_harvest_option(o, "arbitrate_mm", "6");
  EXPECT_DOUBLE_EQ(o.arbitrate_mm, 6.0);
  eval::set_harvest_option(o, "vision_when_nothing", "1");
  EXPECT_TRUE(o.vision_when_nothing);
  EXPECT_NE(why("arbitrate_mm", "1,2").find("one number"), std::string::npos);
  EXPECT_NE(why("probes", "x").find("whole number"), std::string::npos);
  EXPECT_NE(why("probe_rolls_deg", "0,,20").find("not a number"), std::string::npos);
  EXPECT_NE(why("probe_shifts_mm", "200").find("not a number"), std::string::npos);
}

// The planes beside the scan plane are checked before every closing: one
// scan each where the blades close, and a plane that meets something the
// blades would jam on refuses the cut. Moved 25 mm towards the fruit, that
// plane cuts through the fruit itself, so no attempt closes and none jams.
TEST(HarvestTrials, ABladePlaneBesideTheScanThatMeetsTheFruitRefusesTheCut) {
  const Harvested h = scene(sim::TrussClass::kA, 1);
  ASSERT_TRUE(h.result.status.ok()) << h.result.status.message;
  eval::HarvestOptions one_plane;
  one_plane.probes = 0;
  one_plane.blade_plane_shifts_m = {};
  eval::HarvestOptions three_planes = one_plane;
  three_planes.blade_plane_shifts_m = {-0.002, 0.002};
  const auto plain = eval::harvest(laser(), h.scenario, h.result, one_plane);
  const auto beside = eval::harvest(laser(), h.scenario, h.result, three_planes);
  ASSERT_EQ(plain.size(), beside.size());
  int closed_at_first = 0;
  for (std::size_t i = 0; i < plain.size(); ++i) {
    if (plain[i].outcome != eval::HarvestOutcome::kPickedFirst || beside[i].outcome != plain[i].outcome) continue;
    ++closed_at_first;
    EXPECT_EQ(beside[i].scans, plain[i].scans + 2) << "trial " << i;
  }
  EXPECT_GT(closed_at_first, 0);
  eval::HarvestOptions into_fruit = one_plane;
  into_fruit.blade_plane_shifts_m = {-0.025};
  for (const auto& t : eval::harvest(laser(), h.scenario, h.result, into_fruit)) {
    EXPECT_NE(t.outcome, eval::HarvestOutcome::kPickedFirst) << t.cuts;
    EXPECT_NE(t.outcome, eval::HarvestOutcome::kCutFailure) << t.cuts;
    EXPECT_NE(t.why.find("beside the blade plane"), std::string::npos) << t.why;
  }
}

// With pedicel_search the attempt's loop first looks through the tomatoes
// and sweeps the blade plane (several scans), as the verification does;
// without it the loop alone scans.
TEST(HarvestTrials, ThePedicelSearchRunsInTheHarvestWhenAsked) {
  const Harvested h = scene(sim::TrussClass::kA, 1);
  ASSERT_TRUE(h.result.status.ok()) << h.result.status.message;
  eval::HarvestOptions plain;
  eval::HarvestOptions search = plain;
  eval::set_harvest_option(search, "pedicel_search", "1");
  const auto without = eval::harvest(laser(), h.scenario, h.result, plain);
  const auto with = eval::harvest(laser(), h.scenario, h.result, search);
  ASSERT_EQ(without.size(), with.size());
  int attempted = 0;
  for (std::size_t i = 0; i < with.size(); ++i) {
    if (without[i].attempts == 0 || with[i].attempts == 0) continue;
    ++attempted;
    EXPECT_GT(with[i].scans, without[i].scans) << "trial " << i;
  }
  EXPECT_GT(attempted, 0);
}

// Where no cut along the estimated pedicel fits the blades, tilting the
// hypothesis (no_cut_tilts_deg) gives the laser's loop a place to start:
// trials that said "no cut clears the blades" at once get attempts, and
// the checks before closing still decide whether the blades close.
TEST(HarvestTrials, ATiltedHypothesisAttemptsWhereNoCutFitted) {
  eval::HarvestOptions tilted;
  eval::set_harvest_option(tilted, "no_cut_tilts_deg", "15,30");
  ASSERT_EQ(tilted.no_cut_tilts_deg, (std::vector<double>{15, 30}));
  int no_cut_before = 0, attempted_after = 0;
  for (std::uint64_t seed = 1; seed <= 6 && attempted_after == 0; ++seed) {
    const Harvested h = scene(sim::TrussClass::kC, seed);
    ASSERT_TRUE(h.result.status.ok()) << h.result.status.message;
    const auto plain = eval::harvest(laser(), h.scenario, h.result, {});
    const auto with = eval::harvest(laser(), h.scenario, h.result, tilted);
    ASSERT_EQ(plain.size(), with.size());
    for (std::size_t i = 0; i < plain.size(); ++i) {
      if (plain[i].why != "no cut clears the blades") continue;
      ++no_cut_before;
      attempted_after += with[i].why != "no cut clears the blades";
    }
  }
  ASSERT_GT(no_cut_before, 0);
  EXPECT_GT(attempted_after, 0);
}

// The names the help and the errors list are the names the parser takes.
TEST(HarvestTrials, TheListedOptionNamesAreTheOnesTheParserTakes) {
  std::string names = eval::kHarvestOptionNames;
  int listed = 0;
  for (std::size_t at = 0; at < names.size();) {
    const std::size_t end = std::min(names.find(", ", at), names.size());
    const std::string name = names.substr(at, end - at);
    at = end + 2;
    ++listed;
    eval::HarvestOptions o;
    try {
      eval::set_harvest_option(o, name, "?");
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()).find("unknown option"), std::string::npos) << name << ": " << e.what();
    }
  }
  EXPECT_EQ(listed, 14);
}
