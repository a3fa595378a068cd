// SPDX-License-Identifier: Apache-2.0
// Circle fits: exact recovery, degenerate input, Kasa's bias against Hyper,
// the geometric fit against the KCR bound, the reported covariance against
// the observed spread, and robustness to outliers.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/LU>

#include "hydrus_fitting/circle_fit.hpp"
#include <tinyline/common/random.hpp>
#include "montecarlo.hpp"

namespace hf = tinyline::hydrus_fitting;
using ::testing::HasSubstr;

namespace {

constexpr double kPi = std::numbers::pi;

/// n points evenly spread over an arc of `arc_deg` centred on direction `mid_deg`.
Eigen::Matrix2Xd arc(const hf::Circle& c, double arc_deg, int n, double mid_deg = 90.0) {
  Eigen::Matrix2Xd p(2, n);
  const double a0 = (mid_deg - 0.5 * arc_deg) * kPi / 180.0;
  const double step = (arc_deg >= 360.0 ? arc_deg / n : arc_deg / (n - 1)) * kPi / 180.0;
  for (int i = 0; i < n; ++i) {
    const double a = a0 + step * i;
    p.col(i) = c.centre_m + c.radius_m * Eigen::Vector2d(std::cos(a), std::sin(a));
  }
  return p;
}

/// Adds isotropic Gaussian noise of SD sigma to every coordinate.
Eigen::Matrix2Xd noisy(const Eigen::Matrix2Xd& p, double sigma, tinyline::common::SplitMixRandom& rng) {
  Eigen::Matrix2Xd q = p;
  for (Eigen::Index i = 0; i < q.cols(); ++i) {
    q(0, i) += sigma * rng.normal();
    q(1, i) += sigma * rng.normal();
  }
  return q;
}

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}
/// Robust SD of errors around zero: 1.4826 * median |e|.
double robust_sd(const std::vector<double>& e) {
  std::vector<double> a;
  for (double x : e) a.push_back(std::abs(x));
  return 1.4826 * median(a);
}

const hf::Circle kTruth{{0.4, -0.2}, 0.3};

}  // namespace

TEST(CircleFit, ExactPointsRecoveredByEveryFit) {
  for (const double arc_deg : {20.0, 90.0, 360.0}) {
    const auto p = arc(kTruth, arc_deg, 50);
    for (const auto& [name, f] :
         {std::pair{"kasa", hf::fit_circle_kasa(p)}, std::pair{"hyper", hf::fit_circle_hyper(p)},
          std::pair{"taubin", hf::fit_circle_taubin(p)}, std::pair{"geometric", hf::fit_circle(p)},
          std::pair{"robust", hf::fit_circle_robust(p)}}) {
      ASSERT_TRUE(f.ok()) << name << " " << arc_deg << ": " << f.status.message;
      EXPECT_NEAR(f.circle.centre_m.x(), 0.4, 1e-8) << name << " " << arc_deg;
      EXPECT_NEAR(f.circle.centre_m.y(), -0.2, 1e-8) << name << " " << arc_deg;
      EXPECT_NEAR(f.circle.radius_m, 0.3, 1e-8) << name << " " << arc_deg;
      EXPECT_LT(f.rms_residual_m, 1e-8) << name;
    }
  }
}

TEST(CircleFit, ThreePointsGiveTheCircleThroughThem) {
  const auto c = hf::circle_through({1, 0}, {0, 1}, {-1, 0});
  ASSERT_TRUE(c);
  EXPECT_NEAR(c->centre_m.norm(), 0.0, 1e-12);
  EXPECT_NEAR(c->radius_m, 1.0, 1e-12);
  EXPECT_FALSE(hf::circle_through({0, 0}, {1, 1}, {2, 2}));
  EXPECT_FALSE(hf::circle_through({0, 0}, {0, 0}, {2, 1}));
  const auto f = hf::fit_circle_hyper(arc(kTruth, 90, 3));
  ASSERT_TRUE(f.ok()) << f.status.message;
  EXPECT_NEAR(f.circle.radius_m, 0.3, 1e-10);
}

TEST(CircleFit, TooFewPointsIsAnOutcomeWithAReason) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Eigen::Matrix2Xd none(2, 0);
  Eigen::Matrix2Xd two(2, 2);
  two << 0, 1, 0, 1;
  Eigen::Matrix2Xd with_nan(2, 4);
  with_nan << 0, 1, nan, 2, 0, 1, 0, nan;
  for (const auto& p : {none, two, with_nan}) {
    for (const auto& f : {hf::fit_circle_kasa(p), hf::fit_circle_hyper(p), hf::fit_circle_taubin(p), hf::fit_circle(p),
                          hf::fit_circle_robust(p)}) {
      EXPECT_EQ(f.detail, hf::FitStatus::kTooFewPoints);
      EXPECT_THAT(f.status.message, HasSubstr("at least"));
    }
  }
  const auto f = hf::fit_circle_hyper(with_nan);
  EXPECT_EQ(f.non_finite, 2);
  EXPECT_THAT(f.status.message, HasSubstr("2 non-finite skipped"));
}

TEST(CircleFit, NonFinitePointsAreSkippedAndCounted) {
  auto p = arc(kTruth, 120, 30);
  p(0, 3) = std::numeric_limits<double>::quiet_NaN();
  p(1, 7) = std::numeric_limits<double>::infinity();
  for (const auto& f : {hf::fit_circle_kasa(p), hf::fit_circle_hyper(p), hf::fit_circle(p), hf::fit_circle_robust(p)}) {
    ASSERT_TRUE(f.ok()) << f.status.message;
    EXPECT_EQ(f.non_finite, 2);
    EXPECT_NEAR(f.circle.radius_m, 0.3, 1e-8);
  }
}

TEST(CircleFit, CollinearPointsAreAnOutcome) {
  Eigen::Matrix2Xd p(2, 20);
  for (int i = 0; i < 20; ++i) p.col(i) = Eigen::Vector2d(0.1 * i, 0.5 + 0.05 * i);
  for (const auto& f : {hf::fit_circle_kasa(p), hf::fit_circle_hyper(p), hf::fit_circle_taubin(p), hf::fit_circle(p),
                        hf::fit_circle_robust(p)}) {
    EXPECT_EQ(f.detail, hf::FitStatus::kCollinear) << f.status.message;
    EXPECT_EQ(f.status.code, tinyline::common::StatusCode::NotFound);  // valid input without a circle
    EXPECT_THAT(f.status.message, HasSubstr("collinear"));
  }
  // Nearly collinear (a noisy wall): the robust fit refuses radii beyond its range.
  tinyline::common::SplitMixRandom rng(3);
  const auto wall = noisy(p, 0.002, rng);
  hf::RobustCircleParams rp;
  rp.max_radius_m = 1.0;
  const auto r = hf::fit_circle_robust(wall, rp);
  EXPECT_EQ(r.detail, hf::FitStatus::kRadiusOutOfRange) << r.status.message;
}

TEST(CircleFit, InvalidParametersAreNamed) {
  const auto p = arc(kTruth, 90, 20);
  auto with = [](auto set) {
    hf::RobustCircleParams rp;
    set(rp);
    return rp;
  };
  EXPECT_THAT(hf::fit_circle_robust(p, with([](auto& r) { r.inlier_threshold_m = -1; })).status.message,
              HasSubstr("inlier_threshold_m"));
  EXPECT_THAT(hf::fit_circle_robust(p, with([](auto& r) {
                                      r.min_radius_m = 2;
                                      r.max_radius_m = 1;
                                    }))
                  .status.message,
              HasSubstr("min_radius_m"));
  EXPECT_THAT(hf::fit_circle_robust(p, with([](auto& r) { r.known_radius_m = -0.3; })).status.message,
              HasSubstr("known_radius_m"));
  EXPECT_THAT(hf::fit_circle_robust(p, with([](auto& r) { r.confidence = 1.0; })).status.message,
              HasSubstr("confidence"));
  std::vector<double> short_sigma(3, 0.01);
  const auto bad_sigma = hf::fit_circle_robust(p, {}, short_sigma);
  EXPECT_EQ(bad_sigma.detail, hf::FitStatus::kInvalidParams);
  EXPECT_EQ(bad_sigma.status.code, tinyline::common::StatusCode::InvalidArgument);
  EXPECT_EQ(hf::refine_circle(p, kTruth, {}, short_sigma).detail, hf::FitStatus::kInvalidParams);
}

TEST(CircleFit, KcrBoundOfAFullCircleIsTheTextbookValue) {
  // n equally spaced points on a full circle: var(cx) = var(cy) = 2 s^2 / n,
  // var(r) = s^2 / n, no correlations.
  const int n = 64;
  const double s = 0.01;
  const std::vector<double> sig{s};
  const auto b = hf::kcr_bound(arc(kTruth, 360, n), kTruth, sig);
  ASSERT_TRUE(b.status.ok()) << b.status.message;
  EXPECT_NEAR(b.covariance(0, 0), 2 * s * s / n, 1e-12);
  EXPECT_NEAR(b.covariance(1, 1), 2 * s * s / n, 1e-12);
  EXPECT_NEAR(b.covariance(2, 2), s * s / n, 1e-12);
  EXPECT_NEAR(b.covariance(0, 2), 0.0, 1e-12);
  EXPECT_FALSE(hf::kcr_bound(arc(kTruth, 360, 2), kTruth, sig).status.ok());
}

TEST(CircleFit, KasaIsBiasedOnAShortArcAndHyperIsNot) {
  // 60 degree arc, 1 cm noise on a 30 cm radius: Kasa's radius is well known
  // to shrink (it prefers smaller circles); Hyper has no essential bias.
  tinyline::common::SplitMixRandom rng(11);
  const auto truth = arc(kTruth, 60, 40);
  std::vector<double> kasa, hyper, geo;
  for (int t = 0; t < 400; ++t) {
    const auto p = noisy(truth, 0.01, rng);
    kasa.push_back(hf::fit_circle_kasa(p).circle.radius_m - 0.3);
    hyper.push_back(hf::fit_circle_hyper(p).circle.radius_m - 0.3);
    geo.push_back(hf::fit_circle(p).circle.radius_m - 0.3);
  }
  const double sd = robust_sd(hyper);
  EXPECT_LT(median(kasa), -0.5 * sd) << "Kasa should be clearly biased low";
  EXPECT_LT(std::abs(median(hyper)), 0.25 * sd);
  EXPECT_LT(std::abs(median(geo)), 0.25 * sd);
}

TEST(CircleFit, GeometricFitReachesTheKcrBoundAndReportsItsCovariance) {
  // 180 degrees, 60 points, 5 mm noise: the ML fit's spread matches the bound.
  tinyline::common::SplitMixRandom rng(5);
  const auto truth = arc(kTruth, 180, 60);
  const double s = 0.005;
  const std::vector<double> sig{s};
  const auto bound = hf::kcr_bound(truth, kTruth, sig);
  ASSERT_TRUE(bound.status.ok());
  std::vector<double> ex, ey, er, rep_sd_x;
  for (int t = 0; t < 600; ++t) {
    const auto f = hf::fit_circle(noisy(truth, s, rng));
    ASSERT_TRUE(f.ok()) << f.status.message;
    ASSERT_TRUE(f.converged);
    ex.push_back(f.circle.centre_m.x() - kTruth.centre_m.x());
    ey.push_back(f.circle.centre_m.y() - kTruth.centre_m.y());
    er.push_back(f.circle.radius_m - kTruth.radius_m);
    rep_sd_x.push_back(std::sqrt(f.covariance(0, 0)));
  }
  // Isotropic noise in 2-D: the normal component has SD s; robust SDs from
  // 600 samples carry ~5% sampling error.
  EXPECT_NEAR(robust_sd(ex) / std::sqrt(bound.covariance(0, 0)), 1.0, 0.12);
  EXPECT_NEAR(robust_sd(ey) / std::sqrt(bound.covariance(1, 1)), 1.0, 0.12);
  EXPECT_NEAR(robust_sd(er) / std::sqrt(bound.covariance(2, 2)), 1.0, 0.12);
  EXPECT_NEAR(median(rep_sd_x) / std::sqrt(bound.covariance(0, 0)), 1.0, 0.06);
}

// The LM stops at a step shorter than step_tolerance_m without taking it
// (such a step changes the cost at rounding level), and still converges to
// the truth on exact points with the default tolerance; an odd number of
// points exercises the SIMD pass's last lane.
TEST(CircleFit, RefineStopsAtAStepUnderTheTolerance) {
  const hf::Circle truth{{0.3, -0.1}, 0.15};
  const Eigen::Matrix2Xd p = arc(truth, 180.0, 51);
  const hf::Circle start{truth.centre_m + Eigen::Vector2d(5e-4, -3e-4), truth.radius_m + 2e-4};
  hf::RefineParams loose;
  loose.step_tolerance_m = 1e-2;  // the first step (under 1 mm) is under it
  const auto f = hf::refine_circle(p, start, loose);
  ASSERT_TRUE(f.ok()) << f.status.message;
  EXPECT_TRUE(f.converged);
  EXPECT_EQ(f.iterations, 1);
  EXPECT_EQ(f.circle.centre_m, start.centre_m);
  EXPECT_EQ(f.circle.radius_m, start.radius_m);

  const auto g = hf::refine_circle(p, start);
  ASSERT_TRUE(g.ok()) << g.status.message;
  EXPECT_TRUE(g.converged);
  EXPECT_LT(g.iterations, 10);
  EXPECT_NEAR(g.circle.centre_m.x(), truth.centre_m.x(), 1e-12);
  EXPECT_NEAR(g.circle.centre_m.y(), truth.centre_m.y(), 1e-12);
  EXPECT_NEAR(g.circle.radius_m, truth.radius_m, 1e-12);
  EXPECT_LT(g.rms_residual_m, 1e-12);
}

TEST(CircleFit, KnownRadiusFitsOnlyTheCentre) {
  tinyline::common::SplitMixRandom rng(8);
  const auto truth = arc(kTruth, 45, 30);
  const auto p = noisy(truth, 0.003, rng);
  hf::RefineParams rp;
  rp.known_radius_m = 0.3;
  const auto f = hf::fit_circle(p, rp);
  ASSERT_TRUE(f.ok()) << f.status.message;
  EXPECT_DOUBLE_EQ(f.circle.radius_m, 0.3);
  EXPECT_EQ(f.covariance(2, 2), 0.0);
  EXPECT_GT(f.covariance(0, 0), 0.0);
  EXPECT_LT((f.circle.centre_m - kTruth.centre_m).norm(), 0.01);
  // On a short arc the known radius helps a lot over the free fit.
  const auto bk = hf::kcr_bound(truth, kTruth, std::vector<double>{0.003}, true);
  const auto bf = hf::kcr_bound(truth, kTruth, std::vector<double>{0.003}, false);
  const double trace_known = bk.covariance.topLeftCorner<2, 2>().trace();
  const double trace_free = bf.covariance.topLeftCorner<2, 2>().trace();
  EXPECT_LT(trace_known, 0.2 * trace_free);
  // Robust, with 2-point samples.
  hf::RobustCircleParams rob;
  rob.known_radius_m = 0.3;
  const auto r = hf::fit_circle_robust(p, rob);
  ASSERT_TRUE(r.ok()) << r.status.message;
  EXPECT_LT((r.circle.centre_m - f.circle.centre_m).norm(), 1e-6);
}

namespace {

/// 60% points on a 150 degree arc and 40% outliers: a wall behind, a clump
/// (another object) and uniform clutter.
Eigen::Matrix2Xd with_outliers(int n, tinyline::common::SplitMixRandom& rng, std::vector<int>* is_outlier) {
  const int n_in = n * 6 / 10;
  Eigen::Matrix2Xd p(2, n);
  p.leftCols(n_in) = noisy(arc(kTruth, 150, n_in, -90), 0.004, rng);
  is_outlier->assign(static_cast<std::size_t>(n), 0);
  for (int i = n_in; i < n; ++i) {
    (*is_outlier)[static_cast<std::size_t>(i)] = 1;
    const int kind = i % 3;
    if (kind == 0) {
      p.col(i) = Eigen::Vector2d(-0.5 + 1.8 * rng.uniform(), -0.9 + 0.004 * rng.normal());  // wall
    } else if (kind == 1) {
      p.col(i) = Eigen::Vector2d(0.9, -0.4) + 0.03 * Eigen::Vector2d(rng.normal(), rng.normal());  // clump
    } else {
      p.col(i) = Eigen::Vector2d(-0.5 + 1.8 * rng.uniform(), -0.9 + 1.2 * rng.uniform());  // clutter
    }
  }
  return p;
}

}  // namespace

TEST(CircleFit, RobustFitIgnoresFortyPercentOutliers) {
  // Judged in units of the KCR bound of the 120 true points: a robust fit
  // that ignores the outliers is as good as the clean fit, so its squared
  // Mahalanobis error follows chi^2 with 3 dof (median 2.37).
  const auto bound = hf::kcr_bound(arc(kTruth, 150, 120, -90), kTruth, std::vector<double>{0.004});
  ASSERT_TRUE(bound.status.ok());
  const Eigen::Matrix3d info = bound.covariance.inverse();
  tinyline::common::SplitMixRandom rng(21);
  std::vector<double> m2;
  for (int t = 0; t < 50; ++t) {
    std::vector<int> is_out;
    const auto p = with_outliers(200, rng, &is_out);
    hf::RobustCircleParams rp;
    rp.seed = static_cast<std::uint64_t>(t + 1);
    const auto f = hf::fit_circle_robust(p, rp);
    ASSERT_TRUE(f.ok()) << f.status.message;
    const Eigen::Vector3d e(f.circle.centre_m.x() - kTruth.centre_m.x(), f.circle.centre_m.y() - kTruth.centre_m.y(),
                            f.circle.radius_m - kTruth.radius_m);
    m2.push_back(e.dot(info * e));
    EXPECT_LT(m2.back(), 25.0) << "trial " << t << ": error " << e.transpose();
    // Almost every true point is kept, and no point of the clump is.
    int kept_in = 0, kept_clump = 0;
    for (int i = 0; i < 120; ++i) kept_in += f.inlier_mask[static_cast<std::size_t>(i)];
    for (int i = 120; i < 200; ++i) kept_clump += (i % 3 == 1) && f.inlier_mask[static_cast<std::size_t>(i)];
    EXPECT_GE(kept_in, 112);
    EXPECT_EQ(kept_clump, 0);
    // The plain fit on the same points is far off: the outliers matter.
    if (t == 0) {
      EXPECT_GT((hf::fit_circle(p).circle.centre_m - kTruth.centre_m).norm(), 0.05);
    }
  }
  EXPECT_LT(median(m2), 3.6);
}

TEST(CircleFit, RobustFitIsDeterministicForASeed) {
  tinyline::common::SplitMixRandom rng(4);
  std::vector<int> is_out;
  const auto p = with_outliers(150, rng, &is_out);
  hf::RobustCircleParams rp;
  rp.seed = 9;
  const auto a = hf::fit_circle_robust(p, rp);
  const auto b = hf::fit_circle_robust(p, rp);
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a.circle.centre_m, b.circle.centre_m);
  EXPECT_EQ(a.inlier_mask, b.inlier_mask);
  EXPECT_EQ(a.iterations, b.iterations);
}

TEST(CircleFit, ViewpointsRejectCirclesThroughPointsFacingAway) {
  // Two sensors see two arcs of one cylinder; a third, bogus set of points
  // lies on a circle whose near side faces away from its sensor (as points on
  // the robot's own link behind the sensor would). Without viewpoints the fit
  // may pick either; with them only the physically visible circle remains.
  const hf::Circle truth{{0.0, 0.0}, 0.2};
  const hf::Circle bogus{{0.0, 0.55}, 0.2};
  Eigen::Matrix2Xd p(2, 90);
  p.leftCols(30) = arc(truth, 60, 30, -90);      // seen from (0, -1)
  p.middleCols(30, 30) = arc(truth, 60, 30, 0);  // seen from (1, 0)
  p.rightCols(30) = arc(bogus, 110, 30, 90);     // far side of bogus, seen from (0, -1)
  std::vector<Eigen::Vector2d> origins{{0.0, -1.0}, {1.0, 0.0}};
  std::vector<int> sensor(90, 0);
  for (int i = 30; i < 60; ++i) sensor[static_cast<std::size_t>(i)] = 1;
  hf::RobustCircleParams rp;
  rp.inlier_threshold_m = 0.005;
  const auto f = hf::fit_circle_robust(p, rp, {}, {origins, sensor});
  ASSERT_TRUE(f.ok()) << f.status.message;
  EXPECT_LT((f.circle.centre_m - truth.centre_m).norm(), 1e-6);
  EXPECT_EQ(f.points_used, 60);
}

TEST(CircleFit, TaubinAndHyperAgreeToFirstOrder) {
  tinyline::common::SplitMixRandom rng(2);
  const auto p = noisy(arc(kTruth, 120, 80), 0.002, rng);
  const auto h = hf::fit_circle_hyper(p);
  const auto t = hf::fit_circle_taubin(p);
  ASSERT_TRUE(h.ok() && t.ok());
  EXPECT_LT((h.circle.centre_m - t.circle.centre_m).norm(), 1e-3);
}

// The second-order analysis of docs/hydrus_fitting.md: its first-order term
// must be the KCR bound (the Taylor coefficients are read right), and the
// normal x tangential part of the second-order term must be the same for the
// geometric and the Hyper fit (it depends only on the efficient first-order
// influence, which both share) while their normal x normal parts differ.
TEST(CircleFitSecondOrder, FirstOrderIsTheBoundAndTheCrossTermIsShared) {
  namespace ev = tinyline::hydrus_fitting::eval;
  ev::SecondOrderParams p;
  p.arcs_deg = {90};
  p.sigmas_m = {0.019593};
  p.draws = 300;
  const auto rows = ev::second_order_study(p);
  ASSERT_EQ(rows.size(), 4u);  // geometric, hyper, end_weighted, geometric_second_order
  const auto& geo = rows[0];
  const auto& hyp = rows[1];
  ASSERT_EQ(geo.method, "geometric");
  ASSERT_EQ(hyp.method, "hyper");
  for (int k = 0; k < 3; ++k) {
    // 300 draws: the sample variance of a1 is within ~10 % of the bound's.
    EXPECT_NEAR(geo.first_order[k], 1.0, 0.1) << k;
    EXPECT_NEAR(hyp.first_order[k], geo.first_order[k], 1e-6) << k;  // same draws, same first-order term
    EXPECT_NEAR(hyp.a2_split[k][2], geo.a2_split[k][2], 1e-6 + 1e-4 * geo.a2_split[k][2]) << k;
  }
  // At 90 deg and 19.6 mm the cross term is most of the second-order term
  // of the centre's y and the radius, and Hyper's normal x normal part is larger.
  for (const int k : {1, 2}) {
    EXPECT_GT(geo.a2_split[k][2], 0.5 * geo.mse_terms[k][0]) << k;
    EXPECT_GT(hyp.a2_split[k][0], geo.a2_split[k][0]) << k;
  }
}

// The goal's cell the plain fit misses (docs/hydrus_fitting.md): 19.6 mm
// noise (sigma/r = 0.13) on a 120 deg arc. The second-order correction must
// be within 10 % of the KCR bound there (worst of centre x, centre y,
// radius, the study's robust metric) and better than the plain fit on the
// same draws. Seed 3 is neither a seed the constants were chosen on (5, 7)
// nor the reported one (1); 10 000 draws: ~1 % sampling error.
TEST(CircleFitSecondOrder, WithinTenPercentOfTheBoundAtSigmaOverR013On120Degrees) {
  namespace ev = tinyline::hydrus_fitting::eval;
  ev::KcrStudyParams p;
  p.arcs_deg = {120};
  p.sigmas_m = {0.019593};
  p.methods = {ev::Method::kGeometricUnbiased, ev::Method::kGeometricSecondOrder};
  p.trials = 10000;
  p.seed = 3;
  const auto rows = ev::kcr_study(p);
  ASSERT_EQ(rows.size(), 2u);
  const auto worst = [](const ev::KcrRow& r) { return std::max({r.ratio[0], r.ratio[1], r.ratio[2]}); };
  EXPECT_EQ(rows[1].failed, 0);
  EXPECT_LE(worst(rows[1]), 1.10);
  EXPECT_LT(worst(rows[1]), worst(rows[0]) - 0.02) << "plain " << worst(rows[0]) << ", corrected " << worst(rows[1]);
}

// Where the first-order bound is what the fits reach (small sigma/r) the
// correction must leave the efficient fit alone, and on a closed circle
// (no ends, no lean of the radius worth the name) nearly so at any noise.
TEST(CircleFitSecondOrder, LeavesThePlainFitAloneAtLowNoiseAndOnAClosedCircle) {
  const auto fmt_case = [](double arc_deg, double sigma_m) {
    return "worst_sds_arc" + std::to_string(static_cast<int>(arc_deg)) + "_sigma_um" +
           std::to_string(static_cast<int>(sigma_m * 1e6));
  };
  const hf::Circle truth{{0.0, 0.0}, 0.15};
  hf::RefineParams plain;
  plain.remove_radius_bias = true;
  hf::RefineParams corrected = plain;
  corrected.correction = hf::ArcCorrection::kSecondOrder;
  struct Case {
    double arc_deg, sigma_m, tolerance_sds;
  };
  // Tolerances in SDs of the KCR bound, per component and per draw.
  for (const Case c :
       {Case{120, 0.001, 0.02}, Case{120, 0.003625, 0.1}, Case{90, 0.001, 0.03}, Case{360, 0.019593, 0.08}}) {
    double worst = 0.0;
    const Eigen::Matrix2Xd exact = arc(truth, c.arc_deg, 100);
    const std::vector<double> sig{c.sigma_m};
    const hf::KcrBound b = hf::kcr_bound(exact, truth, sig);
    ASSERT_TRUE(b.status.ok());
    tinyline::common::SplitMixRandom rng(11);
    for (int t = 0; t < 200; ++t) {
      const Eigen::Matrix2Xd q = noisy(exact, c.sigma_m, rng);
      const hf::CircleFit a = hf::fit_circle(q, plain);
      const hf::CircleFit f = hf::fit_circle(q, corrected);
      ASSERT_TRUE(a.ok() && f.ok());
      const Eigen::Vector3d d(f.circle.centre_m.x() - a.circle.centre_m.x(),
                              f.circle.centre_m.y() - a.circle.centre_m.y(), f.circle.radius_m - a.circle.radius_m);
      for (int k = 0; k < 3; ++k) {
        ASSERT_LT(std::abs(d(k)), c.tolerance_sds * std::sqrt(b.covariance(k, k)))
            << "arc " << c.arc_deg << " sigma " << c.sigma_m << " draw " << t << " component " << k;
        worst = std::max(worst, std::abs(d(k)) / std::sqrt(b.covariance(k, k)));
      }
      if (c.arc_deg >= 360.0) {
        EXPECT_EQ(f.end_weight_applied, 0.0);
      }
    }
    RecordProperty(fmt_case(c.arc_deg, c.sigma_m), std::to_string(worst));
  }
}

TEST(CircleFitSecondOrder, BadParametersAreNamedAndAKnownRadiusIsLeftAlone) {
  const Eigen::Matrix2Xd p = arc(kTruth, 120, 50);
  hf::RefineParams rp;
  rp.correction = hf::ArcCorrection::kSecondOrder;
  rp.second_order.end_weight = -1.0;
  hf::CircleFit f = hf::refine_circle(p, kTruth, rp);
  EXPECT_EQ(f.detail, hf::FitStatus::kInvalidParams);
  EXPECT_THAT(f.status.message, HasSubstr("end_weight"));
  rp.second_order = {};
  rp.second_order.no_weighting_arc_deg = 90.0;  // below full_weighting_arc_deg
  f = hf::refine_circle(p, kTruth, rp);
  EXPECT_EQ(f.detail, hf::FitStatus::kInvalidParams);
  EXPECT_THAT(f.status.message, HasSubstr("no_weighting_arc_deg"));
  rp.second_order = {};
  rp.second_order.full_weighting_rel_sd_r = 0.3;  // above no_weighting_rel_sd_r
  f = hf::refine_circle(p, kTruth, rp);
  EXPECT_EQ(f.detail, hf::FitStatus::kInvalidParams);
  EXPECT_THAT(f.status.message, HasSubstr("rel_sd_r"));
  rp.second_order = {};
  rp.second_order.mode_shift = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(hf::refine_circle(p, kTruth, rp).detail, hf::FitStatus::kInvalidParams);
  // A known radius: the correction does not apply (centre-only fit).
  tinyline::common::SplitMixRandom rng(4);
  const Eigen::Matrix2Xd q = noisy(p, 0.02, rng);
  rp.second_order = {};
  rp.known_radius_m = kTruth.radius_m;
  f = hf::refine_circle(q, kTruth, rp);
  ASSERT_TRUE(f.ok());
  EXPECT_EQ(f.end_weight_applied, 0.0);
  EXPECT_EQ(f.mode_shift_m, Eigen::Vector3d::Zero());
  EXPECT_STREQ(hf::to_string(hf::ArcCorrection::kSecondOrder), "second_order");
}
