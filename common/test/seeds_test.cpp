// SPDX-License-Identifier: Apache-2.0
// The seed registry: what each seed is for, the labels figures carry, and
// the refusal to tune on held-out seeds.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <tinyline/common/seeds.hpp>

namespace s = tinyline::common::seeds;

TEST(Seeds, EachEvaluationKeepsItsTuningAndHeldOutSeedsApart) {
  for (const auto& e : s::kEvaluations) {
    EXPECT_TRUE(s::disjoint(e)) << e.name;
    EXPECT_FALSE(e.tuning.empty()) << e.name;
    EXPECT_FALSE(e.held_out.empty()) << e.name;
  }
  EXPECT_EQ(s::use_of(s::kLaserClustering, 1), s::SeedUse::kTuning);    // the truss layout was designed on 1-200
  EXPECT_EQ(s::use_of(s::kLaserClustering, 201), s::SeedUse::kTuning);  // looked at while changing the finder
  EXPECT_EQ(s::use_of(s::kLaserClustering, 4001), s::SeedUse::kHeldOut);
  EXPECT_EQ(s::use_of(s::kTomato, 250), s::SeedUse::kTuning);  // the kernel width's fit
  EXPECT_EQ(s::use_of(s::kTomato, 150), s::SeedUse::kHeldOut);
  EXPECT_EQ(s::use_of(s::kHydrus, 5), s::SeedUse::kTuning);
  EXPECT_EQ(s::use_of(s::kHydrus, 6), s::SeedUse::kHeldOut);
  EXPECT_EQ(s::use_of(s::kHydrus, 23), s::SeedUse::kTuning);  // the rule's before/after, looked at
  EXPECT_EQ(s::use_of(s::kHydrus, 1100), s::SeedUse::kHeldOut);
  EXPECT_EQ(s::use_of(s::kCalibration, 1500), s::SeedUse::kHeldOut);
  EXPECT_FALSE(s::use_of(s::kCalibration, 5000).has_value());
}

TEST(Seeds, TheLabelSaysWhichSeedsAndWhatTheyAre) {
  EXPECT_EQ(s::describe(s::kLaserClustering, s::seed_run(4001, 200)), "laser_clustering seeds 4001-4200 (held-out)");
  EXPECT_EQ(s::describe(s::kLaserClustering, s::seed_run(1, 200)), "laser_clustering seeds 1-200 (tuning)");
  EXPECT_EQ(s::describe(s::kTomato, std::vector<std::uint64_t>{1, 5, 6, 7, 150}),
            "tomato seeds 1, 5-7, 150 (mixed: 1, 5-7 tuning, 150 held-out)");
  EXPECT_EQ(s::describe(s::kCalibration, std::vector<std::uint64_t>{2000}), "calibration seeds 2000 (unregistered)");
}

TEST(Seeds, TuningOnHeldOutOrUnregisteredSeedsIsRefused) {
  EXPECT_NO_THROW(s::require_tuning(s::kTomato, s::seed_run(201, 50)));
  try {
    s::require_tuning(s::kTomato, s::seed_run(195, 10));
    FAIL() << "tuning on held-out seeds 195-200 was allowed";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("tomato seeds 195-200"), std::string::npos) << what;
    EXPECT_NE(what.find("tuning: 1-100, 201-300"), std::string::npos) << what;
  }
  EXPECT_THROW(s::require_tuning(s::kHydrus, std::vector<std::uint64_t>{1}), std::invalid_argument);
  EXPECT_THROW(s::require_tuning(s::kCalibration, std::vector<std::uint64_t>{99999}), std::invalid_argument);
}
