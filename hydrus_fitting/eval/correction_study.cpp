// SPDX-License-Identifier: Apache-2.0
#include "correction_study.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

#include <tinyline/common/random.hpp>

#include "hydrus_fitting/circle_fit.hpp"

namespace tinyline::hydrus_fitting::eval {

namespace {

constexpr double kPi = std::numbers::pi;

/// One cell's true points, each point's noise direction (unit; isotropic
/// noise: none) and its noise SD along the circle's normal (for the bound).
struct Cell {
  Circle truth;
  Eigen::Matrix2Xd exact;
  Eigen::Matrix2Xd ray;  ///< per point: the sensor's ray (kRays)
  std::vector<double> normal_sd;
};

Cell make_cell(const CorrectionStudyParams& p, double arc_deg, int n, double sigma, NoiseKind noise) {
  Cell c;
  c.truth = Circle{{0.0, 0.0}, p.radius_m};
  c.exact.resize(2, n);
  c.ray.resize(2, n);
  c.normal_sd.assign(static_cast<std::size_t>(n), sigma);
  const bool closed = arc_deg >= 360.0;
  const double span = arc_deg * kPi / 180.0;
  const double step = closed ? span / n : span / (n - 1);
  const double a0 = kPi / 2 - 0.5 * span;  // centred on +y
  const Eigen::Vector2d sensor(0.0, p.radius_m + p.sensor_distance_m);
  for (int i = 0; i < n; ++i) {
    const double a = a0 + step * i;
    const Eigen::Vector2d u(std::cos(a), std::sin(a));
    c.exact.col(i) = p.radius_m * u;
    c.ray.col(i) = (c.exact.col(i) - sensor).normalized();
    if (noise == NoiseKind::kRays) c.normal_sd[static_cast<std::size_t>(i)] = sigma * std::abs(c.ray.col(i).dot(u));
  }
  return c;
}

/// Whether one sensor facing the arc's middle sees every point of it (ray noise only then).
bool visible(const CorrectionStudyParams& p, double arc_deg) {
  const double d = p.radius_m + p.sensor_distance_m;
  return arc_deg * kPi / 180.0 < 2.0 * std::acos(p.radius_m / d) - 0.05;
}

double median_abs(std::vector<double> e) {
  for (double& x : e) x = std::abs(x);
  const auto mid = e.begin() + static_cast<long>(e.size() / 2);
  std::nth_element(e.begin(), mid, e.end());
  return *mid;
}

double root_mean_square(const std::vector<double>& e) {
  double s = 0;
  for (const double x : e) s += x * x;
  return std::sqrt(s / static_cast<double>(e.size()));
}

/// The three fits of one noise draw: plain, correction always, as shipped.
std::array<CircleFit, 3> fit_three(const Eigen::Matrix2Xd& pts, double outliers, double sigma, std::uint64_t seed) {
  RefineParams plain;
  plain.remove_radius_bias = true;
  RefineParams always = plain, shipped = plain;
  always.correction = shipped.correction = ArcCorrection::kSecondOrder;
  always.second_order.max_sigma_over_r = std::numeric_limits<double>::infinity();
  always.second_order.max_points = std::numeric_limits<int>::max();
  std::array<CircleFit, 3> out;
  const RefineParams* rp[3] = {&plain, &always, &shipped};
  for (int k = 0; k < 3; ++k) {
    if (outliers > 0.0) {
      RobustCircleParams r;
      r.inlier_threshold_m = 4.0 * sigma;  // the node's rule: a few SDs of the range noise
      r.max_radius_m = 100.0;
      r.seed = seed;
      r.refine = *rp[k];
      out[static_cast<std::size_t>(k)] = fit_circle_robust(pts, r);
    } else {
      out[static_cast<std::size_t>(k)] = fit_circle(pts, *rp[k]);
    }
  }
  return out;
}

CorrectionRow run_cell(const CorrectionStudyParams& p, double arc, int n, double rel_sigma, double outliers,
                       NoiseKind noise) {
  const double sigma = rel_sigma * p.radius_m;
  const Cell cell = make_cell(p, arc, n, sigma, noise);
  CorrectionRow row;
  row.arc_deg = arc;
  row.points = n;
  row.sigma_over_r = rel_sigma;
  row.outlier_fraction = outliers;
  row.noise = noise;
  row.trials = p.trials;
  const KcrBound b = kcr_bound(cell.exact, cell.truth, cell.normal_sd);
  common::SplitMixRandom rng(
      common::mix_seed(p.seed, static_cast<std::uint64_t>(arc * 10 + n * 1000),
                       static_cast<std::uint64_t>(rel_sigma * 1e4 + outliers * 1e3 + 7 * int(noise))));
  std::vector<double> err[3][3];  // [fit][component]
  int applied = 0;
  Eigen::Matrix2Xd noisy(2, n);
  for (int t = 0; t < p.trials; ++t) {
    for (int i = 0; i < n; ++i) {
      if (outliers > 0.0 && rng.uniform() < outliers) {  // anywhere in the box around the circle
        noisy.col(i) = Eigen::Vector2d(3.0 * rng.uniform() - 1.5, 3.0 * rng.uniform() - 1.5) * p.radius_m;
      } else if (noise == NoiseKind::kRays) {
        noisy.col(i) = cell.exact.col(i) + sigma * rng.normal() * cell.ray.col(i);
      } else {
        noisy.col(i) = cell.exact.col(i) + sigma * Eigen::Vector2d(rng.normal(), rng.normal());
      }
    }
    const auto fits = fit_three(noisy, outliers, sigma, static_cast<std::uint64_t>(t + 1));
    if (!fits[0].ok() || !fits[1].ok() || !fits[2].ok()) {
      ++row.failed;
      continue;
    }
    applied += fits[2].second_order_applied ? 1 : 0;
    for (int k = 0; k < 3; ++k) {
      const Circle& c = fits[static_cast<std::size_t>(k)].circle;
      err[k][0].push_back(c.centre_m.x() - cell.truth.centre_m.x());
      err[k][1].push_back(c.centre_m.y() - cell.truth.centre_m.y());
      err[k][2].push_back(c.radius_m - cell.truth.radius_m);
    }
  }
  const int ok = p.trials - row.failed;
  row.applied_share = ok > 0 ? double(applied) / ok : std::nan("");
  for (int k = 0; k < 3; ++k) {
    for (int c = 0; c < 3; ++c) {
      const double sd = b.status.ok() ? std::sqrt(b.covariance(c, c)) : std::nan("");
      if (err[k][c].empty() || !(sd > 0)) {
        row.robust[k] = row.rms[k] = std::nan("");
        continue;
      }
      row.robust[k] = std::max(row.robust[k], 1.4826 * median_abs(err[k][c]) / sd);
      row.rms[k] = std::max(row.rms[k], root_mean_square(err[k][c]) / sd);
    }
  }
  return row;
}

}  // namespace

std::vector<CorrectionRow> correction_study(const CorrectionStudyParams& p) {
  std::vector<CorrectionRow> rows;
  for (const NoiseKind noise : p.noise)
    for (const double outliers : p.outlier_fractions)
      for (const double arc : p.arcs_deg) {
        if (noise == NoiseKind::kRays && !visible(p, arc)) continue;
        for (const int n : p.points)
          for (const double rel : p.sigma_over_r) rows.push_back(run_cell(p, arc, n, rel, outliers, noise));
      }
  return rows;
}

std::string correction_csv(const std::vector<CorrectionRow>& rows) {
  std::string s =
      "noise,outlier_fraction,arc_deg,points,sigma_over_r,trials,failed,applied_share,robust_plain,robust_always,"
      "robust_shipped,rms_plain,rms_always,rms_shipped\n";
  for (const auto& r : rows) {
    s += fmt::format("{},{},{},{},{},{},{},{:.4f}", r.noise == NoiseKind::kRays ? "rays" : "isotropic",
                     r.outlier_fraction, r.arc_deg, r.points, r.sigma_over_r, r.trials, r.failed, r.applied_share);
    for (const auto* v : {r.robust, r.rms})
      for (int k = 0; k < 3; ++k) s += fmt::format(",{:.4f}", v[k]);
    s += "\n";
  }
  return s;
}

}  // namespace tinyline::hydrus_fitting::eval
