// Laser verification on simulated trusses (small N; the full run is the
// documented `tomato_eval --verify` command in docs/tomato_reasoning.md).
#include <gtest/gtest.h>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/pipeline.hpp"
#ifdef TINYLINE_TOMATO_HAVE_LASER
#include "tomato_reasoning/eval/verification.hpp"
#endif

using namespace tinyline;
using namespace tinyline::tomato_reasoning;

#ifdef TINYLINE_TOMATO_HAVE_LASER
TEST(LaserVerification, ConfirmsOrRelocatesThePedicelOfSimpleTrusses) {
  eval::VerificationOptions o;
  o.calibration_sets = 1;  // a lighter calibration rail than the scoring's (seconds less)
  o.calibration_step_m = 0.02;
  eval::VerificationHarness as_recognised(o);
  o.random_offset_m = 0.05;
  eval::VerificationHarness offset(o);
  int trials = 0, aligned = 0, offset_trials = 0, offset_aligned = 0, offset_vision = 0;
  for (std::uint64_t seed : {1u, 2u, 3u, 4u}) {
    const eval::Scenario s = eval::make_scenario(sim::TrussClass::kA, seed);
    PipelineParams p;
    p.gravity = s.gravity_camera;
    const PipelineResult r = TomatoPipeline(p).run(s.cloud());
    ASSERT_TRUE(r.ok) << r.reason;
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
#endif
