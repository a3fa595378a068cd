// SPDX-License-Identifier: Apache-2.0
// The harness's scoring on an idealised scanner (central rays only, Gaussian
// range noise): the verdict logic and the confidence intervals. The reported
// figures come from the simulated sensor, never from this scanner.
#include <cmath>
#include <map>
#include <random>

#include <gtest/gtest.h>

#include "harness.hpp"

namespace ev = tinyline::laser_clustering::eval;
namespace lc = tinyline::laser_clustering;
namespace sim = tinyline::sim;

namespace {

class IdealScanner : public ev::Scanner {
 public:
  ev::SimulatedScan scan(const sim::World& world, const Eigen::Isometry3d& T, std::uint64_t index) override {
    std::mt19937_64 rng(index);
    std::normal_distribution<double> noise(0.0, 0.001);
    ev::SimulatedScan s;
    const double fov = 60.0 * std::numbers::pi / 180.0;
    for (int i = 0; i < 256; ++i) {
      const double a = -fov / 2 + fov * i / 255.0;
      sim::Ray r;
      r.origin = T.translation();
      r.dir = T.linear() * Eigen::Vector3d(std::sin(a), 0.0, std::cos(a));
      const auto h = world.raycast(r, 1e-9, 2.0);
      s.scan.angle_rad.push_back(a);
      s.scan.range_m.push_back(h ? h->t_m + noise(rng) : std::nan(""));
      s.scan.reflectance.push_back(h ? 10.0 * world.material_of(*h).effective_albedo() : std::nan(""));
      s.truth_object.push_back(h ? h->object : sim::kNoObject);
      s.truth_mixed.push_back(0);
    }
    return s;
  }
  std::string describe() const override { return "ideal central rays"; }
};

}  // namespace

TEST(EvalHarness, WilsonIntervalsMatchScipy) {
  // References: scipy.stats.binomtest(k, n).proportion_ci(method="wilson").
  const struct {
    int k, n;
    double lo, hi;
  } ref[] = {{56, 61, 0.8220533819707464, 0.9644804333931264},
             {26, 39, 0.5097739439934599, 0.7936704381040163},
             {0, 10, 0.0, 0.27753279986288926},
             {200, 200, 0.9811546736227335, 1.0},
             {97, 100, 0.9154806357094724, 0.9897454759759611}};
  for (const auto& r : ref) {
    const ev::Rate w = ev::wilson(r.k, r.n);
    EXPECT_NEAR(w.lo, r.lo, 1e-12) << r.k << "/" << r.n;
    EXPECT_NEAR(w.hi, r.hi, 1e-12) << r.k << "/" << r.n;
    EXPECT_DOUBLE_EQ(w.p, static_cast<double>(r.k) / r.n);
  }
  EXPECT_EQ(ev::wilson(0, 0).n, 0);
}

TEST(EvalHarness, TrussVerdictsAreConsistentWithTheTruth) {
  IdealScanner scanner;
  int observed = 0;
  const auto r = ev::run_truss_case(
      ev::TrussCase::kRandomOffset, scanner, 60, 1000, {},
      [&](const ev::TrussTrial& t, const ev::TrussScene& scene, const ev::SimulatedScan&, const lc::TwoStageResult&,
          const lc::PedicelDetection& d) {
        ++observed;
        if (t.verdict == ev::Verdict::kAligned) {
          EXPECT_EQ(t.chosen, scene.truth.target_pedicel);
          EXPECT_LE(std::abs(t.lateral_error_m), 0.01);
        }
        if (t.verdict == ev::Verdict::kOutOfView || t.verdict == ev::Verdict::kMissed) {
          EXPECT_TRUE(d.outcome != lc::PedicelOutcome::kMove && d.outcome != lc::PedicelOutcome::kCutHere);
        }
      });
  EXPECT_EQ(observed, 60);
  ASSERT_EQ(r.trials.size(), 60u);
  // The rates are the trials' own verdicts recounted (a sum of the four
  // counts would hold whatever the tally did).
  std::map<ev::Verdict, int> verdicts;
  int ambiguous = 0, unambiguous = 0, aligned_unambiguous = 0;
  for (const auto& t : r.trials) {
    ++verdicts[t.verdict];
    ambiguous += t.neighbour_nearer;
    unambiguous += !t.neighbour_nearer;
    aligned_unambiguous += !t.neighbour_nearer && t.verdict == ev::Verdict::kAligned;
  }
  EXPECT_EQ(r.aligned.k, verdicts[ev::Verdict::kAligned]);
  EXPECT_EQ(r.wrong.k, verdicts[ev::Verdict::kWrong]);
  EXPECT_EQ(r.out_of_view.k, verdicts[ev::Verdict::kOutOfView]);
  EXPECT_EQ(r.missed.k, verdicts[ev::Verdict::kMissed]);
  EXPECT_EQ(r.ambiguous.k, ambiguous);
  EXPECT_EQ(r.aligned_unambiguous.k, aligned_unambiguous);
  EXPECT_EQ(r.aligned_unambiguous.n, unambiguous);
  // Ideal rays see the 6 mm rods clearly: most trials align.
  EXPECT_GE(r.aligned.k, 45);
}

TEST(EvalHarness, StickAndWrenchCasesRunAndScore) {
  IdealScanner scanner;
  const auto st = ev::run_stick_case(scanner, 20, 7);
  EXPECT_EQ(st.trials.size(), 20u);
  // Ideal reflectance separates the metal every time.
  EXPECT_EQ(st.reflectance_correct.k, 20);
  const auto wr = ev::run_wrench_case(scanner, 5, 3);
  EXPECT_EQ(wr.trials.size(), 5u);
  // The ideal rays' reflectance does not change with the pitch (no specular
  // lobe): the search must say it found no peak, never report a pitch (the
  // old check, an absolute error >= 0, held whatever it reported).
  EXPECT_EQ(wr.found.k, 0);
  for (const auto& t : wr.trials) EXPECT_TRUE(std::isinf(t.error_rad)) << t.error_rad;
}
