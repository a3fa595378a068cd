// SPDX-License-Identifier: Apache-2.0
// DBSCAN semantics on hand-made cases, and the three neighbour searches
// (FLANN, brute force, ordered-scan fast path) agreeing label for label.
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "laser_clustering/dbscan.hpp"

namespace lc = tinyline::laser_clustering;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

namespace {

Eigen::MatrixXd line_1d(const std::vector<double>& xs) {
  Eigen::MatrixXd p(1, static_cast<Eigen::Index>(xs.size()));
  for (std::size_t i = 0; i < xs.size(); ++i) p(0, static_cast<Eigen::Index>(i)) = xs[i];
  return p;
}

void expect_same(const lc::DbscanResult& a, const lc::DbscanResult& b, const char* what) {
  ASSERT_TRUE(a.status.ok()) << what << ": " << a.status.message;
  ASSERT_TRUE(b.status.ok()) << what << ": " << b.status.message;
  EXPECT_EQ(a.labels, b.labels) << what;
  EXPECT_EQ(a.is_core, b.is_core) << what;
  EXPECT_EQ(a.num_clusters, b.num_clusters) << what;
}

}  // namespace

TEST(Dbscan, CoreBorderNoiseOnALine) {
  // 0,1,2 dense (core with eps 1, min 3); 3 is a border of that cluster (its
  // only neighbours are 2 and itself); 10 is noise.
  const auto p = line_1d({0.0, 1.0, 2.0, 3.0, 10.0});
  const auto r = lc::dbscan(p, {1.0, 3});
  ASSERT_TRUE(r.status.ok()) << r.status.message;
  EXPECT_THAT(r.labels, ElementsAre(0, 0, 0, 0, lc::kNoise));
  EXPECT_THAT(r.is_core, ElementsAre(0, 1, 1, 0, 0));
  EXPECT_EQ(r.num_clusters, 1);
  EXPECT_EQ(r.num_core, 2u);
  EXPECT_EQ(r.num_noise, 1u);
}

TEST(Dbscan, TakesFixedSizeEigenPointsWithoutCopying) {
  Eigen::Matrix3Xd p(3, 4);
  p << 0, 0.1, 0.2, 5,  //
      0, 0, 0, 0,       //
      0, 0, 0, 0;
  const auto r = lc::dbscan(p, {.eps = 0.15, .min_points = 2});
  ASSERT_TRUE(r.status.ok());
  EXPECT_THAT(r.labels, ElementsAre(0, 0, 0, lc::kNoise));
}

TEST(Dbscan, NeighbourAtExactlyEpsCounts) {
  // Distances of exactly eps (exact in binary) are neighbours: |p-q|^2 <= eps^2.
  const auto p = line_1d({0.0, 0.5, 1.0});
  const auto r = lc::dbscan(p, {0.5, 3});
  ASSERT_TRUE(r.status.ok());
  EXPECT_THAT(r.is_core, ElementsAre(0, 1, 0));
  EXPECT_THAT(r.labels, ElementsAre(0, 0, 0));
}

TEST(Dbscan, BorderReachableFromTwoClustersJoinsLowerNumberedCluster) {
  // Groups at 6..8 and 0..2 (eps 2, min 4); the point at 4 has neighbours
  // {2, 4, 6} only, so it is a border point within eps of both clusters.
  const auto p = line_1d({8.0, 7.5, 7.0, 6.5, 6.0, 4.0, 2.0, 1.5, 1.0, 0.5, 0.0});
  const auto r = lc::dbscan(p, {2.0, 4});
  ASSERT_TRUE(r.status.ok());
  EXPECT_EQ(r.is_core[5], 0);
  EXPECT_EQ(r.num_clusters, 2);
  // Clusters are numbered by their lowest-indexed core point: the group at
  // 6..8 holds index 0, so it is cluster 0, and the border joins it.
  EXPECT_EQ(r.labels[0], 0);
  EXPECT_EQ(r.labels[10], 1);
  EXPECT_EQ(r.labels[5], 0);
  // Reversing the order reverses the numbering; the border stays with cluster 0,
  // which is now the group at 0..2.
  const auto q = line_1d({0.0, 0.5, 1.0, 1.5, 2.0, 4.0, 6.0, 6.5, 7.0, 7.5, 8.0});
  const auto s = lc::dbscan(q, {2.0, 4});
  ASSERT_TRUE(s.status.ok());
  EXPECT_EQ(s.labels[0], 0);
  EXPECT_EQ(s.labels[5], 0);
  EXPECT_EQ(s.labels[10], 1);
  expect_same(s, lc::dbscan_brute_force(q, {2.0, 4}), "border rule");
}

TEST(Dbscan, MinPointsOneMakesEveryPointCore) {
  const auto p = line_1d({0.0, 5.0, 5.5});
  const auto r = lc::dbscan(p, {1.0, 1});
  ASSERT_TRUE(r.status.ok());
  EXPECT_THAT(r.is_core, ElementsAre(1, 1, 1));
  EXPECT_THAT(r.labels, ElementsAre(0, 1, 1));
}

TEST(Dbscan, MinPointsAboveSizeMakesEverythingNoise) {
  const auto p = line_1d({0.0, 0.1, 0.2});
  const auto r = lc::dbscan(p, {1.0, 4});
  ASSERT_TRUE(r.status.ok());
  EXPECT_THAT(r.labels, ElementsAre(lc::kNoise, lc::kNoise, lc::kNoise));
  EXPECT_EQ(r.num_clusters, 0);
}

TEST(Dbscan, DuplicatesCountAsSeparateNeighbours) {
  const auto p = line_1d({3.0, 3.0, 3.0});
  const auto r = lc::dbscan(p, {1e-9, 3});
  ASSERT_TRUE(r.status.ok());
  EXPECT_THAT(r.labels, ElementsAre(0, 0, 0));
}

TEST(Dbscan, RejectsBadParameters) {
  const auto p = line_1d({0.0, 1.0});
  for (const double eps :
       {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    const auto r = lc::dbscan(p, {eps, 2});
    EXPECT_FALSE(r.status.ok());
    EXPECT_THAT(r.status.message, HasSubstr("eps"));
    EXPECT_TRUE(r.labels.empty());
    const auto b = lc::dbscan_brute_force(p, {eps, 2});
    EXPECT_FALSE(b.status.ok());
  }
  const auto r = lc::dbscan(p, {1.0, 0});
  EXPECT_FALSE(r.status.ok());
  EXPECT_THAT(r.status.message, HasSubstr("min_points must be >= 1 (got 0)"));
  EXPECT_FALSE(lc::validate(lc::DbscanParams{1.0, -3}).ok());
  EXPECT_TRUE(lc::validate(lc::DbscanParams{}).ok());
}

TEST(Dbscan, EmptyInputIsAnExplicitEmptyResult) {
  const Eigen::MatrixXd p(3, 0);
  const auto r = lc::dbscan(p, {});
  EXPECT_TRUE(r.status.ok());
  EXPECT_TRUE(r.labels.empty());
  EXPECT_EQ(r.note, "empty input");
  const auto s = lc::dbscan_ordered_scan({}, {});
  EXPECT_TRUE(s.status.ok());
  EXPECT_EQ(s.note, "empty input");
}

TEST(Dbscan, ZeroDimensionalPointsAreRejected) {
  const Eigen::MatrixXd p(0, 4);
  const auto r = lc::dbscan(p, {});
  EXPECT_FALSE(r.status.ok());
  EXPECT_THAT(r.status.message, HasSubstr("dimension 0"));
}

TEST(Dbscan, NonFinitePointsAreInvalidAndIgnored) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Eigen::MatrixXd p(2, 5);
  p << 0.0, nan, 0.1, 0.2, std::numeric_limits<double>::infinity(),  //
      0.0, 0.0, 0.0, 0.0, 0.0;
  for (const auto& r : {lc::dbscan(p, {0.15, 2}), lc::dbscan_brute_force(p, {0.15, 2})}) {
    ASSERT_TRUE(r.status.ok());
    EXPECT_THAT(r.labels, ElementsAre(0, lc::kInvalid, 0, 0, lc::kInvalid));
    EXPECT_EQ(r.num_invalid, 2u);
    EXPECT_EQ(r.num_noise, 0u);
  }
  Eigen::MatrixXd all_bad = Eigen::MatrixXd::Constant(2, 3, nan);
  const auto r = lc::dbscan(all_bad, {});
  ASSERT_TRUE(r.status.ok());
  EXPECT_THAT(r.labels, ElementsAre(lc::kInvalid, lc::kInvalid, lc::kInvalid));
  EXPECT_THAT(r.note, HasSubstr("no valid points"));
}

TEST(Dbscan, FlannMatchesBruteForceOnRandomBlobsInSeveralDimensions) {
  std::mt19937 rng(7);
  for (const int dim : {1, 2, 3, 5, 8}) {
    for (int trial = 0; trial < 10; ++trial) {
      const int n = 50 + 40 * trial;
      Eigen::MatrixXd p(dim, n);
      std::normal_distribution<double> g(0.0, 1.0);
      std::uniform_int_distribution<int> centre(0, 4);
      for (int i = 0; i < n; ++i) {
        const int c = centre(rng);
        for (int d = 0; d < dim; ++d) p(d, i) = 4.0 * c * ((d % 2) ? 1.0 : -1.0) + g(rng);
      }
      const lc::DbscanParams params{0.4 + 0.2 * (trial % 5), 1 + trial % 6};
      expect_same(lc::dbscan(p, params), lc::dbscan_brute_force(p, params), "random blobs");
    }
  }
}

TEST(Dbscan, FlannMatchesBruteForceOnLatticeTies) {
  // Integer lattice with eps 1: every axis neighbour sits at exactly eps.
  Eigen::MatrixXd p(3, 5 * 5 * 4);
  int k = 0;
  for (int a = 0; a < 5; ++a)
    for (int b = 0; b < 5; ++b)
      for (int c = 0; c < 4; ++c) p.col(k++) << a, b * (c % 2 ? 1 : 2), c;
  for (int m = 1; m <= 8; ++m) {
    expect_same(lc::dbscan(p, {1.0, m}), lc::dbscan_brute_force(p, {1.0, m}), "lattice");
  }
}

namespace {

// A synthetic ordered scan: a few surfaces, gaps, noise, invalid pixels.
struct TestScan {
  std::vector<double> angle, range, feature;
};

TestScan random_scan(std::mt19937& rng, int pixels, bool descending) {
  TestScan s;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  const double fov = 70.0 * std::numbers::pi / 180.0;
  double level = 0.1 + 0.4 * u(rng);
  for (int i = 0; i < pixels; ++i) {
    double a = -fov / 2 + fov * i / (pixels - 1);
    s.angle.push_back(descending ? -a : a);
    if (u(rng) < 0.05) level = 0.05 + 0.6 * u(rng);  // jump to another surface
    double r = level + 0.004 * g(rng);
    if (u(rng) < 0.03) r = std::numeric_limits<double>::quiet_NaN();
    if (u(rng) < 0.02) r = 0.05 + u(rng);  // an outlier
    s.range.push_back(r);
    s.feature.push_back(u(rng) < 0.5 ? 0.0 : 0.02 * g(rng));
  }
  return s;
}

}  // namespace

TEST(Dbscan, OrderedScanFastPathMatchesBruteForce) {
  std::mt19937 rng(11);
  lc::OrderedScanDbscan fast;  // reused across calls, as a node does
  for (int trial = 0; trial < 200; ++trial) {
    const auto s = random_scan(rng, 256, trial % 3 == 0);
    const bool with_feature = trial % 4 == 1;
    lc::OrderedScanPoints scan{s.angle, s.range,
                               with_feature ? std::span<const double>(s.feature) : std::span<const double>()};
    const lc::DbscanParams params{0.002 + 0.001 * (trial % 40), 1 + trial % 9};
    const auto points = lc::to_points(scan);
    const auto ref = lc::dbscan_brute_force(points, params);
    expect_same(fast.run(scan, params), ref, "ordered scan vs brute force");
    expect_same(lc::dbscan(points, params), ref, "flann vs brute force");
  }
}

// The run-joining pass's shortcuts (a run already joined, a run at another
// depth, a window that cannot reach past its run) are exact: a wall cut into
// many runs by thin near objects (pedicels), some gaps narrower than eps and
// some wider, must cluster as brute force does, with stage 1's eps and
// min_points and around them.
TEST(Dbscan, OrderedScanMatchesBruteForceOnSurfacesCutByThinObjects) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  lc::OrderedScanDbscan fast;
  const double fov = 40.0 * std::numbers::pi / 180.0;
  for (int trial = 0; trial < 300; ++trial) {
    TestScan s;
    const int pixels = 256;
    const double wall = 0.15 + 0.5 * u(rng), tilt = 0.2 * (u(rng) - 0.5);
    int in_object = 0;
    double object_r = 0.0;
    for (int i = 0; i < pixels; ++i) {
      const double a = -fov / 2 + fov * i / (pixels - 1);
      s.angle.push_back(trial % 2 ? -a : a);
      if (in_object == 0 && u(rng) < 0.06) {
        in_object = 1 + static_cast<int>(6 * u(rng));
        object_r = wall - (0.005 + 0.08 * u(rng));
      }
      double r = wall + tilt * a + 0.002 * g(rng);
      if (in_object > 0) {
        --in_object;
        r = object_r + 0.001 * g(rng);
      }
      if (u(rng) < 0.02) r = std::numeric_limits<double>::quiet_NaN();
      s.range.push_back(r);
      s.feature.push_back(0.01 * g(rng));
    }
    const bool with_feature = trial % 5 == 4;
    lc::OrderedScanPoints scan{s.angle, s.range,
                               with_feature ? std::span<const double>(s.feature) : std::span<const double>()};
    const lc::DbscanParams params{0.01 + 0.005 * (trial % 7), 2 + trial % 5};
    const auto ref = lc::dbscan_brute_force(lc::to_points(scan), params);
    expect_same(fast.run(scan, params), ref, "cut surfaces: ordered scan vs brute force");
  }
}

TEST(Dbscan, OrderedScanWithEpsLargerThanRangeSearchesEverything) {
  // eps beyond the range: every pixel may neighbour every other.
  std::vector<double> angle{-1.0, -0.5, 0.0, 0.5, 1.0}, range{0.1, 0.1, 0.1, 0.1, 0.1};
  lc::OrderedScanPoints scan{angle, range, {}};
  const auto r = lc::dbscan_ordered_scan(scan, {0.5, 5});
  const auto ref = lc::dbscan_brute_force(lc::to_points(scan), {0.5, 5});
  expect_same(r, ref, "huge eps");
  EXPECT_THAT(r.labels, ElementsAre(0, 0, 0, 0, 0));
}

TEST(Dbscan, OrderedScanRejectsNonMonotoneAnglesAndShapeMismatch) {
  std::vector<double> angle{0.0, 0.1, 0.05}, range{1.0, 1.0, 1.0};
  const auto r = lc::dbscan_ordered_scan({angle, range, {}}, {});
  EXPECT_FALSE(r.status.ok());
  EXPECT_THAT(r.status.message, HasSubstr("strictly monotone"));
  EXPECT_THAT(r.status.message, HasSubstr("pixel 2"));
  std::vector<double> short_range{1.0};
  const auto s = lc::dbscan_ordered_scan({angle, short_range, {}}, {});
  EXPECT_FALSE(s.status.ok());
  EXPECT_THAT(s.status.message, HasSubstr("3 angles but 1 ranges"));
  const auto t = lc::dbscan_ordered_scan({angle, range, {}}, {-0.1, 2});
  EXPECT_FALSE(t.status.ok());
  EXPECT_THAT(t.status.message, HasSubstr("eps"));
}

TEST(Dbscan, OrderedScanInvalidPixelsDoNotBreakMonotonicity) {
  // Invalid pixels (NaN or non-positive range) are skipped, whatever their angle.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> angle{0.0, 0.01, nan, 0.02, 0.03}, range{0.3, 0.3, 0.3, -1.0, 0.3};
  const auto r = lc::dbscan_ordered_scan({angle, range, {}}, {0.01, 2});
  ASSERT_TRUE(r.status.ok()) << r.status.message;
  EXPECT_THAT(r.labels, ElementsAre(0, 0, lc::kInvalid, lc::kInvalid, 0));
  std::vector<double> all_nan(5, nan);
  const auto s = lc::dbscan_ordered_scan({angle, all_nan, {}}, {0.01, 2});
  ASSERT_TRUE(s.status.ok());
  EXPECT_EQ(s.num_invalid, 5u);
  EXPECT_THAT(s.note, HasSubstr("no valid points"));
}
