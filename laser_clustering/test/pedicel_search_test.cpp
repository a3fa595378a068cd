// SPDX-License-Identifier: Apache-2.0
// The pedicel search on hand-made sweeps: planes along the expected pedicel
// where one scan alone chooses the peduncle, sees nothing, or takes a
// sepal's tip, and the fused sweep ends on the pedicel or refuses.
#include <cmath>
#include <functional>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "laser_clustering/pedicel_search.hpp"
#include "synthetic_scan.hpp"

namespace lc = tinyline::laser_clustering;
using lc::PedicelOutcome;
using lc::test::Disc;
using lc::test::synth_scan;
using lc::test::SynthParams;
using ::testing::HasSubstr;

namespace tinyline::laser_clustering {
inline void PrintTo(PedicelOutcome o, std::ostream* os) { *os << to_string(o); }
}  // namespace tinyline::laser_clustering

namespace {

constexpr double kRod = 0.003;  // a pedicel's radius [m]

// The expected pedicel: the blade throat, as the vision put it.
lc::PedicelExpectation expected() {
  lc::PedicelExpectation e;
  e.position_xz_m = Eigen::Vector2d(0.0, 0.12);
  e.sd_m = 0.015;
  return e;
}

// One scan per height of the default plan, the discs each plane cuts.
std::vector<lc::SweepScan> sweep(const std::function<std::vector<Disc>(double)>& scene, unsigned seed) {
  std::vector<lc::SweepScan> out;
  const lc::PedicelFinderParams finder;
  for (double h : lc::PedicelSearchParams{}.heights_m) {
    SynthParams sp;
    sp.wall_z_m = 0.40;
    sp.seed = seed++;
    const auto s = synth_scan(scene(h), sp);
    out.push_back({h, lc::find_pedicel(s.scan, lc::cluster_line_scan(s.scan), finder, expected())});
  }
  return out;
}

const lc::PedicelDetection& at_height_0(const std::vector<lc::SweepScan>& planes) {
  for (const auto& p : planes) {
    if (p.height_m == 0.0) return p.detection;
  }
  throw std::logic_error("no plane at height 0");
}

}  // namespace

TEST(PedicelSearch, APedicelAlongTheSweepBeatsAPeduncleNearerTheExpectedPoint) {
  // The pedicel hangs 2 cm beside the expected point, tilted a little; the
  // peduncle crosses the planes at a slant, 3 mm from it at height 0.
  const auto planes = sweep(
      [](double h) {
        return std::vector<Disc>{{0.02 + 0.2 * h, 0.125, kRod, 6.0, 1}, {0.003 - 2.0 * h, 0.118, kRod, 6.0, 2}};
      },
      11);
  const lc::PedicelDetection& one = at_height_0(planes);
  ASSERT_TRUE(one.outcome == PedicelOutcome::kMove || one.outcome == PedicelOutcome::kCutHere) << one.reason;
  EXPECT_NEAR(one.position_xz_m.x(), 0.003, 0.004) << "one scan alone takes the peduncle";

  const lc::PedicelSearchResult r = lc::fuse_sweep(planes, lc::PedicelFinderParams{}, expected());
  ASSERT_EQ(r.detection.outcome, PedicelOutcome::kMove) << r.detection.reason;
  EXPECT_NEAR(r.detection.position_xz_m.x(), 0.02, 0.003);
  EXPECT_NEAR(r.detection.lateral_offset_m, 0.02, 0.003);
  ASSERT_FALSE(r.tracks.empty());
  EXPECT_EQ(r.tracks.front().planes_seen, static_cast<int>(planes.size()));
  EXPECT_EQ(r.cut_height_m, 0.0);
  EXPECT_NEAR(r.tracks.front().slope.x(), 0.2, 0.15);
}

TEST(PedicelSearch, APedicelHiddenAtTheCutIsFoundFromThePlanesAbove) {
  // At heights 0 and below a fruit in front hides the pedicel; above it,
  // the pedicel is in the clear: the cut goes to the nearest plane there.
  const auto planes = sweep(
      [](double h) {
        std::vector<Disc> d{{0.012, 0.13, kRod, 6.0, 1}};
        if (h <= 0.0) d.push_back({0.0, 0.07, 0.025, 6.0, 2});
        return d;
      },
      21);
  EXPECT_EQ(at_height_0(planes).outcome, PedicelOutcome::kNothingToCut) << at_height_0(planes).reason;

  const lc::PedicelSearchResult r = lc::fuse_sweep(planes, lc::PedicelFinderParams{}, expected());
  ASSERT_EQ(r.detection.outcome, PedicelOutcome::kMove) << r.detection.reason;
  EXPECT_NEAR(r.detection.position_xz_m.x(), 0.012, 0.003);
  EXPECT_NEAR(r.detection.position_xz_m.y(), 0.13, 0.005);
  EXPECT_GT(r.cut_height_m, 0.0);
  EXPECT_LE(r.cut_height_m, 0.005 + 1e-12);
}

TEST(PedicelSearch, AThinThingInOnePlaneOnlyIsRefused) {
  // A sepal's tip reaches the cut's plane beside the throat; nothing else
  // thin is there.
  const auto planes = sweep(
      [](double h) {
        return h == 0.0 ? std::vector<Disc>{{0.003, 0.12, kRod, 6.0, 1}} : std::vector<Disc>{};
      },
      31);
  ASSERT_EQ(at_height_0(planes).outcome, PedicelOutcome::kCutHere) << "one scan alone would cut it";

  const lc::PedicelSearchResult r = lc::fuse_sweep(planes, lc::PedicelFinderParams{}, expected());
  EXPECT_EQ(r.detection.outcome, PedicelOutcome::kNothingToCut);
  EXPECT_THAT(r.detection.reason, HasSubstr("none on a pedicel's track"));
  EXPECT_TRUE(r.tracks.empty());

  lc::PedicelSearchParams any;
  any.min_planes = 1;
  EXPECT_EQ(lc::fuse_sweep(planes, lc::PedicelFinderParams{}, expected(), any).detection.outcome,
            PedicelOutcome::kCutHere);
}

TEST(PedicelSearch, BadInputIsAnsweredWithAReason) {
  auto planes = sweep([](double) { return std::vector<Disc>{{0.0, 0.12, kRod, 6.0, 1}}; }, 41);
  lc::PedicelSearchParams bad;
  bad.miss_factor = 0.0;
  const auto r = lc::fuse_sweep(planes, lc::PedicelFinderParams{}, expected(), bad);
  EXPECT_EQ(r.detection.outcome, PedicelOutcome::kInvalidInput);
  EXPECT_THAT(r.detection.reason, HasSubstr("miss_factor"));

  planes.erase(planes.begin());  // the height-0 plane
  const auto none = lc::fuse_sweep(planes, lc::PedicelFinderParams{}, expected());
  EXPECT_EQ(none.detection.outcome, PedicelOutcome::kInvalidInput);
  EXPECT_THAT(none.detection.reason, HasSubstr("height 0"));
}
