// SPDX-License-Identifier: Apache-2.0
// The named stages inside the clustering, each against its own contract
// (the headers in src/ are not installed; the whole pipelines are tested in
// dbscan_test, two_stage_test and the brute-force agreement).
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "dbscan_internal.hpp"
#include "two_stage_steps.hpp"

namespace lc = tinyline::laser_clustering;
namespace detail = tinyline::laser_clustering::detail;

TEST(ClusteringStages, BearingHalfWindowBoundsTheExactWindowFromAbove) {
  const double eps = 0.03;
  double previous = 0.0;
  for (double x = 1e-4; x < 1.0; x += 1e-3) {  // x = eps / r
    const double w = detail::bearing_half_window(eps, eps / x);
    EXPECT_GE(w, std::asin(x)) << "eps / r = " << x;
    EXPECT_GE(w, previous) << "grows with eps / r";
    previous = w;
  }
  EXPECT_EQ(detail::bearing_half_window(eps, eps), 2.0 * std::numbers::pi) << "within eps of the sensor: every bearing";
  EXPECT_EQ(detail::bearing_half_window(eps, 0.5 * eps), 2.0 * std::numbers::pi);
}

TEST(ClusteringStages, ReferenceMedianIsTheElementNthElementPicks) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.1, 0.5);
  for (int trial = 0; trial < 200; ++trial) {
    const int cnt = 1 + trial % detail::kMaxReferencePx;
    std::vector<double> r(static_cast<std::size_t>(cnt + 4));
    for (auto& v : r) v = trial % 3 == 0 ? std::round(u(rng) * 20.0) / 20.0 : u(rng);  // ties too
    std::vector<double> sorted(r.begin() + 2, r.begin() + 2 + cnt);
    std::nth_element(sorted.begin(), sorted.begin() + cnt / 2, sorted.end());
    EXPECT_EQ(detail::reference_median(r.data(), 2, 2 + cnt - 1), sorted[static_cast<std::size_t>(cnt / 2)])
        << cnt << " values";
  }
}

TEST(ClusteringStages, AMixedPixelLiesInTheMiddleHalfOfAStep) {
  const lc::EdgeFilterParams e;  // mixed step 15 mm + 3 % of the range
  EXPECT_TRUE(detail::is_mixed_pixel(0.20, 0.22, 0.24, e)) << "half-way down a 4 cm step";
  EXPECT_TRUE(detail::is_mixed_pixel(0.24, 0.22, 0.20, e)) << "either direction";
  EXPECT_FALSE(detail::is_mixed_pixel(0.20, 0.205, 0.24, e)) << "on the near side of the step";
  EXPECT_FALSE(detail::is_mixed_pixel(0.20, 0.235, 0.24, e)) << "on the far side of the step";
  EXPECT_FALSE(detail::is_mixed_pixel(0.20, 0.205, 0.21, e)) << "a 1 cm slope is no step";
}

TEST(ClusteringStages, PeelingDropsTheDraggedEndsAndKeepsTheMinimum) {
  const lc::EdgeFilterParams e;  // up to 4 pixels per end, 18 mm + 3 % of the range
  // Two dragged pixels before a flat 30 cm surface, one after it.
  const std::vector<double> r{0.40, 0.35, 0.30, 0.301, 0.299, 0.30, 0.302, 0.30, 0.36};
  const auto peel = detail::peel_dragged_ends(r.data(), 0, static_cast<int>(r.size()) - 1, e);
  EXPECT_EQ(peel.lo, 2);
  EXPECT_EQ(peel.hi, 7);
  // A steep ramp looks dragged everywhere: peeling stops at min_keep_px points.
  const std::vector<double> ramp{0.10, 0.15, 0.20, 0.25, 0.30, 0.35};
  const auto kept = detail::peel_dragged_ends(ramp.data(), 0, 5, e);
  EXPECT_EQ(kept.lo, 4);
  EXPECT_EQ(kept.hi - kept.lo + 1, e.min_keep_px);
}

TEST(ClusteringStages, SmoothingNeverAveragesAcrossADepthStep) {
  const lc::EdgeFilterParams e;  // half width 2, 12 mm + 3 % of the range
  const std::vector<double> r{0.200, 0.202, 0.198, 0.250, 0.252, 0.248};
  EXPECT_DOUBLE_EQ(detail::smoothed_range(r.data(), 2, 0, 5, e), (0.200 + 0.202 + 0.198) / 3.0);
  EXPECT_DOUBLE_EQ(detail::smoothed_range(r.data(), 3, 0, 5, e), (0.250 + 0.252 + 0.248) / 3.0);
  EXPECT_DOUBLE_EQ(detail::smoothed_range(r.data(), 0, 0, 0, e), 0.200) << "alone: itself";
}

TEST(ClusteringStages, InFrontLooksAtTheNextTwoValidPixels) {
  const lc::EdgeFilterParams e;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  lc::LineScan s;
  s.range_m = {0.30, 0.30, nan, 0.29, 0.20, 0.30};
  for (std::size_t i = 0; i < s.range_m.size(); ++i) s.angle_rad.push_back(0.01 * static_cast<double>(i));
  EXPECT_TRUE(detail::in_front(s, 0.30, 1, +1, e)) << "the second valid pixel (past an invalid one) is in front";
  EXPECT_FALSE(detail::in_front(s, 0.30, 0, +1, e)) << "the third is not looked at";
  EXPECT_FALSE(detail::in_front(s, 0.30, 5, +1, e)) << "nothing beyond the scan";
  EXPECT_FALSE(detail::in_front(s, 0.30, 1, -1, e));
}
