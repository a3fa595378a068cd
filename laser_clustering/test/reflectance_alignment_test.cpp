// SPDX-License-Identifier: Apache-2.0
// Reflectance clustering (Figure 5.8) and the alignment search (5.3.2) on
// hand-made data.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "laser_clustering/alignment_search.hpp"
#include "laser_clustering/reflectance_clustering.hpp"
#include "synthetic_scan.hpp"

namespace lc = tinyline::laser_clustering;
using lc::AlignmentOutcome;
using lc::test::synth_scan;
using lc::test::SynthParams;
using ::testing::HasSubstr;

namespace tinyline::laser_clustering {
inline void PrintTo(AlignmentOutcome o, std::ostream* os) { *os << to_string(o); }
}  // namespace tinyline::laser_clustering

namespace {

// Figure 5.8 B: a metal stick (reflectance 37, Table 3.2 wrench) whose front
// is `gap_m` before a cardboard wall (4.8) at 0.30 m; range noise as the real
// sensor's at 30 cm (Table 3.2 SD about 4 mm), reflectance noise 5 %.
lc::test::SynthScan stick_scene(unsigned seed, double gap_m) {
  SynthParams sp;
  sp.wall_z_m = 0.30;
  sp.wall_reflectance = 4.8;
  sp.noise_sd_m = 0.004;
  sp.seed = seed;
  const double radius = 0.005;
  auto s = synth_scan({{0.01, 0.30 - gap_m + radius, radius, 37.0, 1}}, sp);
  std::mt19937 rng(seed + 1000);
  std::normal_distribution<double> g(0.0, 0.05);
  for (auto& r : s.scan.reflectance) r *= std::exp(g(rng));
  return s;
}

// Intersection over union of the stick's pixels and the cluster holding most
// of them, over pure pixels (mixed pixels at the stick's edges belong to
// neither side and are not scored).
double stick_iou(const std::vector<int>& labels, const lc::test::SynthScan& s) {
  std::vector<int> truth = s.truth;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (s.purity[i] < 0.9) truth[i] = -2;
  }
  std::vector<int> votes;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (truth[i] == 1 && labels[i] >= 0) {
      if (votes.size() <= static_cast<std::size_t>(labels[i])) votes.resize(static_cast<std::size_t>(labels[i]) + 1);
      ++votes[static_cast<std::size_t>(labels[i])];
    }
  }
  if (votes.empty()) return 0.0;
  const int best = static_cast<int>(std::max_element(votes.begin(), votes.end()) - votes.begin());
  int inter = 0, uni = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (truth[i] == -2) continue;
    const bool a = truth[i] == 1, b = labels[i] == best;
    inter += a && b;
    uni += a || b;
  }
  return uni ? static_cast<double>(inter) / uni : 0.0;
}

}  // namespace

TEST(ReflectanceClustering, StickNearBackgroundSeparatesOnlyWithReflectance) {
  int with = 0, without = 0;
  const int trials = 100;
  for (int t = 0; t < trials; ++t) {
    const auto s = stick_scene(static_cast<unsigned>(t + 1), 0.004);
    lc::ReflectanceClusteringParams p;
    const auto r = lc::cluster_by_reflectance(s.scan, p);
    ASSERT_TRUE(r.status.ok()) << r.status.message;
    with += stick_iou(r.labels, s) >= 0.8;
    p.use_reflectance = false;
    const auto d = lc::cluster_by_reflectance(s.scan, p);
    ASSERT_TRUE(d.status.ok());
    without += stick_iou(d.labels, s) >= 0.8;
  }
  EXPECT_GE(with, 95) << "of " << trials;
  EXPECT_LE(without, 5) << "distance alone should merge the stick into the wall";
}

TEST(ReflectanceClustering, BrightestClusterIsTheMetal) {
  const auto s = stick_scene(3, 0.004);
  const auto r = lc::cluster_by_reflectance(s.scan);
  ASSERT_TRUE(r.status.ok());
  ASSERT_GE(r.brightest, 0);
  const auto& c = r.clusters[static_cast<std::size_t>(r.brightest)];
  EXPECT_NEAR(c.median_reflectance, 37.0, 4.0);
  EXPECT_NEAR(c.centroid_xz_m.x(), 0.01, 0.002);
  EXPECT_NEAR(c.width_m, 0.010, 0.003);
}

TEST(ReflectanceClustering, BadInput) {
  const auto s = stick_scene(1, 0.004);
  lc::LineScan no_refl = s.scan;
  no_refl.reflectance.clear();
  auto r = lc::cluster_by_reflectance(no_refl);
  EXPECT_EQ(r.status.code, tinyline::StatusCode::InvalidArgument);
  EXPECT_THAT(r.status.message, HasSubstr("needs a reflectance per pixel"));
  lc::ReflectanceClusteringParams p;
  p.use_reflectance = false;
  EXPECT_TRUE(lc::cluster_by_reflectance(no_refl, p).status.ok()) << "distance-only needs no reflectance";
  p = {};
  p.reflectance_ratio_at_eps = 1.0;
  EXPECT_THAT(lc::cluster_by_reflectance(s.scan, p).status.message,
              HasSubstr("reflectance_ratio_at_eps must be in [1.0001, 1000], got 1"));
  p = {};
  p.dbscan.eps = -1.0;
  EXPECT_THAT(lc::cluster_by_reflectance(s.scan, p).status.message, HasSubstr("eps_m must be in"));
  // Zero and NaN reflectance: those pixels are left out and counted.
  lc::LineScan holes = s.scan;
  holes.reflectance[10] = 0.0;
  holes.reflectance[11] = std::numeric_limits<double>::quiet_NaN();
  r = lc::cluster_by_reflectance(holes);
  ASSERT_TRUE(r.status.ok());
  EXPECT_EQ(r.labels[10], lc::kInvalid);
  EXPECT_EQ(r.labels[11], lc::kInvalid);
  EXPECT_THAT(r.note, HasSubstr("2 pixels without a positive reflectance"));
  // Empty and all-invalid.
  EXPECT_EQ(lc::cluster_by_reflectance(lc::LineScan{}).note, "empty scan");
  lc::LineScan dark = s.scan;
  for (auto& x : dark.range_m) x = std::numeric_limits<double>::quiet_NaN();
  r = lc::cluster_by_reflectance(dark);
  EXPECT_TRUE(r.status.ok());
  EXPECT_EQ(r.brightest, -1);
  // Finite figures on invalid pixels are saturated pixels' lower bounds
  // (line_scan.hpp): without them, or when told not to use them, nothing.
  lc::SurfaceReflectanceParams valid_only;
  valid_only.use_saturated = false;
  auto sr = lc::surface_reflectance(dark, valid_only);
  EXPECT_EQ(sr.status.code, tinyline::StatusCode::NotFound);
  EXPECT_THAT(sr.status.message, HasSubstr("no valid pixel with a reflectance in pixels 0..255"));
  for (auto& x : dark.reflectance) x = std::numeric_limits<double>::quiet_NaN();
  sr = lc::surface_reflectance(dark);
  EXPECT_EQ(sr.status.code, tinyline::StatusCode::NotFound);
  EXPECT_THAT(sr.status.message, HasSubstr("no valid pixel with a reflectance in pixels 0..255"));
  lc::SurfaceReflectanceParams by_cluster;
  by_cluster.method = lc::SurfaceReflectanceParams::Method::kBrightestCluster;
  const auto sc = lc::surface_reflectance(dark, by_cluster);
  EXPECT_EQ(sc.status.code, tinyline::StatusCode::NotFound);
  EXPECT_THAT(sc.status.message, HasSubstr("no reflectance cluster: no valid pixels"));
}

namespace {

// A specular lobe over pitch: Gaussian of width sigma around p0 over a diffuse floor.
std::vector<lc::AlignmentSample> sweep(double p0, double sigma, double step, double from, double to, double noise,
                                       std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, noise);
  std::vector<lc::AlignmentSample> s;
  for (double p = from; p <= to + 1e-12; p += step) {
    const double r = 5.0 + 32.0 * std::exp(-0.5 * std::pow((p - p0) / sigma, 2));
    s.push_back({p, r * std::exp(g(rng))});
  }
  return s;
}

constexpr double kDeg = std::numbers::pi / 180.0;

}  // namespace

TEST(AlignmentSearch, RefinesThePeakBetweenSteps) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-8.0, 8.0);
  std::vector<double> err_noiseless, err_noisy;
  for (int t = 0; t < 200; ++t) {
    const double p0 = u(rng) * kDeg;
    const auto clean = sweep(p0, 4.0 * kDeg, 2.0 * kDeg, -20 * kDeg, 20 * kDeg, 0.0, rng);
    const auto a = lc::find_alignment(clean);
    ASSERT_EQ(a.outcome, AlignmentOutcome::kFound) << a.status.message;
    EXPECT_TRUE(a.refined);
    err_noiseless.push_back(std::abs(a.best_pitch_rad - p0));
    auto noisy = sweep(p0, 4.0 * kDeg, 2.0 * kDeg, -20 * kDeg, 20 * kDeg, 0.05, rng);
    std::shuffle(noisy.begin(), noisy.end(), rng);  // order does not matter
    const auto b = lc::find_alignment(noisy);
    ASSERT_EQ(b.outcome, AlignmentOutcome::kFound) << b.status.message;
    err_noisy.push_back(std::abs(b.best_pitch_rad - p0));
  }
  std::sort(err_noiseless.begin(), err_noiseless.end());
  std::sort(err_noisy.begin(), err_noisy.end());
  // The lobe sits on a floor, so log is not exactly a parabola: small bias remains.
  EXPECT_LT(err_noiseless.back(), 0.35 * kDeg);
  EXPECT_LT(err_noisy[err_noisy.size() / 2], 0.5 * kDeg);
  // Better than the raw step: the best sample alone is off by up to 1 degree.
  EXPECT_LT(err_noiseless[err_noiseless.size() / 2], 0.25 * kDeg);
}

TEST(AlignmentSearch, EdgeFlatAndTooFewSamples) {
  std::mt19937 rng(2);
  const auto edge = sweep(12 * kDeg, 4 * kDeg, 2 * kDeg, -10 * kDeg, 10 * kDeg, 0.0, rng);
  const auto a = lc::find_alignment(edge);
  EXPECT_EQ(a.outcome, AlignmentOutcome::kAtSweepEdge);
  EXPECT_EQ(a.status.code, tinyline::StatusCode::NotFound);
  EXPECT_THAT(a.status.message, HasSubstr("highest pitch"));
  EXPECT_NEAR(a.best_pitch_rad, 10 * kDeg, 1e-9);

  std::vector<lc::AlignmentSample> flat{{0.0, 5.0}, {0.1, 5.1}, {0.2, 4.9}, {0.3, 5.0}};
  EXPECT_EQ(lc::find_alignment(flat).outcome, AlignmentOutcome::kNoPeak);
  EXPECT_EQ(lc::find_alignment(flat).status.code, tinyline::StatusCode::NotFound);

  std::vector<lc::AlignmentSample> few{
      {0.0, 5.0}, {0.1, std::numeric_limits<double>::quiet_NaN()}, {0.2, -1.0}, {0.3, 9.0}};
  const auto f = lc::find_alignment(few);
  EXPECT_EQ(f.outcome, AlignmentOutcome::kInvalidInput);
  EXPECT_EQ(f.status.code, tinyline::StatusCode::InvalidArgument);
  EXPECT_THAT(f.status.message, HasSubstr("need at least 3 usable pitches, got 2 (2 samples skipped"));
  EXPECT_EQ(lc::find_alignment({}).outcome, AlignmentOutcome::kInvalidInput);

  lc::AlignmentParams p;
  p.fit_half_width = 0;
  EXPECT_THAT(lc::find_alignment(flat, p).status.message, HasSubstr("fit_half_width must be in [1, 50], got 0"));
}

TEST(AlignmentSearch, RepeatedPitchesAreAveraged) {
  std::vector<lc::AlignmentSample> s{{-0.1, 10.0}, {0.0, 30.0}, {0.0, 34.0}, {0.1, 10.0}, {0.2, 5.0}, {-0.2, 5.0}};
  const auto a = lc::find_alignment(s);
  ASSERT_EQ(a.outcome, AlignmentOutcome::kFound);
  EXPECT_EQ(a.num_samples, 5);
  EXPECT_NEAR(a.best_pitch_rad, 0.0, 1e-9);  // symmetric neighbours
  EXPECT_NEAR(a.peak_reflectance, 32.0, 1e-9);
}

TEST(AlignmentSearch, SurfaceReflectanceOfTheMetal) {
  const auto s = stick_scene(5, 0.004);
  // The stick covers about 7 of 256 pixels: the top 2 % are metal.
  lc::SurfaceReflectanceParams q;
  q.quantile = 0.98;
  const auto r = lc::surface_reflectance(s.scan, q);
  ASSERT_TRUE(r.status.ok()) << r.status.message;
  EXPECT_NEAR(r.reflectance, 37.0, 4.0);
  // The same from the brightest cluster.
  lc::SurfaceReflectanceParams c;
  c.method = lc::SurfaceReflectanceParams::Method::kBrightestCluster;
  const auto rc = lc::surface_reflectance(s.scan, c);
  ASSERT_TRUE(rc.status.ok()) << rc.status.message;
  EXPECT_NEAR(rc.reflectance, 37.0, 4.0);
  // A region of interest without the stick sees the wall only.
  lc::SurfaceReflectanceParams left = q;
  left.last_pixel = 100;
  const auto rl = lc::surface_reflectance(s.scan, left);
  ASSERT_TRUE(rl.status.ok());
  EXPECT_LT(rl.reflectance, 7.0);
}

TEST(AlignmentSearch, SurfaceReflectanceRejectsBadParameters) {
  const auto s = stick_scene(5, 0.004);
  lc::SurfaceReflectanceParams p;
  p.quantile = 0.0;
  EXPECT_THAT(lc::surface_reflectance(s.scan, p).status.message,
              HasSubstr("surface_quantile must be in [0.01, 1], got 0"));
  p = {};
  p.first_pixel = 50;
  p.last_pixel = 10;
  EXPECT_THAT(lc::surface_reflectance(s.scan, p).status.message,
              HasSubstr("last_pixel (10) is before first_pixel (50)"));
  lc::LineScan no_refl = s.scan;
  no_refl.reflectance.clear();
  EXPECT_THAT(lc::surface_reflectance(no_refl).status.message, HasSubstr("0 reflectance values for 256 pixels"));
}

// A specular peak that saturates: its pixels have no distance; their
// fewest-pulse light at the neighbours' range bounds their reflectance from
// below, and the top quantile then sees the peak instead of its shoulders.
TEST(AlignmentSearch, SaturatedPixelsCountAsLowerBoundsOfThePeak) {
  lc::LineScan s;
  const std::size_t n = 40;
  std::vector<std::uint8_t> saturated(n, 0);
  std::vector<double> intensity(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    s.angle_rad.push_back(-0.2 + 0.01 * static_cast<double>(i));
    s.range_m.push_back(0.25);
    s.reflectance.push_back(i >= 15 && i < 25 ? 9000.0 : 3000.0);  // metal shoulders, then panel
  }
  for (std::size_t i = 18; i < 22; ++i) {  // the peak saturates: no range, no figure
    s.range_m[i] = std::numeric_limits<double>::quiet_NaN();
    s.reflectance[i] = std::numeric_limits<double>::quiet_NaN();
    saturated[i] = 1;
    intensity[i] = 30.0;  // charge_unit per pulse at the fewest-pulse read-out, clipped
  }
  saturated[0] = 1;  // saturated but valid (inconsistent input): left alone
  intensity[0] = 30.0;
  lc::LineScan bounded = s;
  EXPECT_EQ(lc::saturated_reflectance_bound(bounded, saturated, intensity), 4u);
  // 25 cm: 625 cm^2 * 30 * 10 = 187500, above every valid pixel.
  for (std::size_t i = 18; i < 22; ++i) EXPECT_DOUBLE_EQ(bounded.reflectance[i], 625.0 * 30.0 * 10.0);
  EXPECT_DOUBLE_EQ(bounded.reflectance[0], 3000.0);
  EXPECT_FALSE(bounded.valid(19)) << "a bound, not a distance";

  lc::SurfaceReflectanceParams p;
  p.quantile = 0.95;
  const auto with = lc::surface_reflectance(bounded, p);
  ASSERT_TRUE(with.status.ok()) << with.status.message;
  EXPECT_DOUBLE_EQ(with.reflectance, 187500.0);
  p.use_saturated = false;
  const auto without = lc::surface_reflectance(bounded, p);
  ASSERT_TRUE(without.status.ok());
  EXPECT_DOUBLE_EQ(without.reflectance, 9000.0) << "the shoulders only";

  // No valid neighbour within the gap: no bound. Mismatched sizes: nothing done.
  lc::LineScan lonely = s;
  for (std::size_t i = 10; i < 30; ++i) lonely.range_m[i] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(lc::saturated_reflectance_bound(lonely, saturated, intensity, 4), 0u);
  intensity.pop_back();
  EXPECT_EQ(lc::saturated_reflectance_bound(bounded, saturated, intensity), 0u);
}
