// SPDX-License-Identifier: Apache-2.0
#include "montecarlo.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

#include <tinyline/common/random.hpp>
#include "hydrus_fitting/estimator.hpp"
#include "planar_scene.hpp"

namespace tinyline::hydrus_fitting::eval {

namespace {

constexpr double kPi = std::numbers::pi;

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  const auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

/// 1.4826 median |e|: the RMS of a Gaussian's errors, robust to outliers.
double robust_rms(const std::vector<double>& e) {
  std::vector<double> a;
  a.reserve(e.size());
  for (const double x : e) a.push_back(std::abs(x));
  return 1.4826 * median(a);
}

Eigen::Matrix2Xd arc_points(const Circle& c, double arc_deg, int n) {
  Eigen::Matrix2Xd p(2, n);
  const bool closed = arc_deg >= 360.0;
  const double span = arc_deg * kPi / 180.0;
  const double step = closed ? span / n : span / (n - 1);
  const double a0 = kPi / 2 - 0.5 * span;  // centred on +y, like a sensor below looking up
  for (int i = 0; i < n; ++i) {
    const double a = a0 + step * i;
    p.col(i) = c.centre_m + c.radius_m * Eigen::Vector2d(std::cos(a), std::sin(a));
  }
  return p;
}

/// What the kcr_study's geometric_second_order (and second_order_study's) runs.
RefineParams second_order_params() {
  RefineParams rp;
  rp.remove_radius_bias = true;
  rp.correction = ArcCorrection::kSecondOrder;
  return rp;
}

}  // namespace

const char* to_string(Method m) {
  switch (m) {
    case Method::kKasa: return "kasa";
    case Method::kHyper: return "hyper";
    case Method::kGeometric: return "geometric";
    case Method::kGeometricUnbiased: return "geometric_unbiased";
    case Method::kGeometricSecondOrder: return "geometric_second_order";
    case Method::kRobust: return "robust";
    case Method::kKnownRadius: return "known_radius";
  }
  return "?";
}

namespace {

/// One trial's fit of `noisy` by method `m` (trial `t` seeds the robust fit).
CircleFit fit_by(Method m, const Eigen::Matrix2Xd& noisy, const KcrStudyParams& p, const Circle& truth, double sigma,
                 int t) {
  switch (m) {
    case Method::kKasa: return fit_circle_kasa(noisy);
    case Method::kHyper: return fit_circle_hyper(noisy);
    case Method::kGeometric: return fit_circle(noisy);
    case Method::kGeometricUnbiased: {
      RefineParams rp;
      rp.remove_radius_bias = true;
      return fit_circle(noisy, rp);
    }
    case Method::kGeometricSecondOrder: return fit_circle(noisy, second_order_params());
    case Method::kRobust: {
      RobustCircleParams rp;
      rp.inlier_threshold_m = 4.0 * sigma;  // the node's rule: a few SDs of the range noise
      rp.max_radius_m = 100.0;
      rp.seed = static_cast<std::uint64_t>(t + 1);
      return fit_circle_robust(noisy, rp);
    }
    case Method::kKnownRadius: {
      RefineParams rp;
      rp.known_radius_m = p.radius_m;
      const CircleFit h = fit_circle_hyper(noisy);
      return refine_circle(noisy, h.ok() ? Circle{h.circle.centre_m, p.radius_m} : truth, rp);
    }
  }
  return {};
}

/// The errors (cx, cy, r) and reported SDs of one method's trials.
struct TrialErrors {
  std::vector<double> err[3], rep[3];
};

/// Runs one method's trials at one arc and noise level; counts failures in `row`.
TrialErrors run_kcr_trials(const KcrStudyParams& p, const Circle& truth, const Eigen::Matrix2Xd& exact, double arc,
                           double sigma, KcrRow& row) {
  // The same noise draws for every method (paired comparison).
  common::SplitMixRandom rng(p.seed + static_cast<std::uint64_t>(arc * 1000) + static_cast<std::uint64_t>(sigma * 1e7));
  TrialErrors out;
  Eigen::Matrix2Xd noisy(2, p.points);
  for (int t = 0; t < p.trials; ++t) {
    for (int i = 0; i < p.points; ++i) {
      noisy(0, i) = exact(0, i) + sigma * rng.normal();
      noisy(1, i) = exact(1, i) + sigma * rng.normal();
    }
    const CircleFit f = fit_by(row.method, noisy, p, truth, sigma, t);
    if (!f.ok()) {
      ++row.failed;
      continue;
    }
    const double e[3] = {f.circle.centre_m.x() - truth.centre_m.x(), f.circle.centre_m.y() - truth.centre_m.y(),
                         f.circle.radius_m - truth.radius_m};
    for (int k = 0; k < 3; ++k) {
      out.err[k].push_back(e[k]);
      out.rep[k].push_back(std::sqrt(std::max(0.0, f.covariance(k, k))));
    }
  }
  return out;
}

/// The row's robust RMSE, bias, spread and ratios to the bound `b`.
void summarise_kcr(const TrialErrors& te, const KcrBound& b, KcrRow& row) {
  for (int k = 0; k < 3; ++k) {
    if (row.method == Method::kKnownRadius && k == 2) continue;
    row.kcr_sd[k] = std::sqrt(b.covariance(k, k));
    row.rmse[k] = robust_rms(te.err[k]);
    row.bias[k] = median(te.err[k]);
    std::vector<double> d;
    for (const double x : te.err[k]) d.push_back(std::abs(x - row.bias[k]));
    row.spread[k] = 1.4826 * median(d);
    row.ratio[k] = row.kcr_sd[k] > 0 ? row.rmse[k] / row.kcr_sd[k] : std::nan("");
    row.reported_sd_ratio[k] = row.kcr_sd[k] > 0 ? median(te.rep[k]) / row.kcr_sd[k] : std::nan("");
  }
}

}  // namespace

std::vector<KcrRow> kcr_study(const KcrStudyParams& p) {
  std::vector<KcrRow> rows;
  const Circle truth{{0.0, 0.0}, p.radius_m};
  for (const double arc : p.arcs_deg) {
    const Eigen::Matrix2Xd exact = arc_points(truth, arc, p.points);
    for (const double sigma : p.sigmas_m) {
      const std::vector<double> sig{sigma};
      const KcrBound free_bound = kcr_bound(exact, truth, sig, false);
      const KcrBound known_bound = kcr_bound(exact, truth, sig, true);
      for (const Method m : p.methods) {
        KcrRow row;
        row.arc_deg = arc;
        row.sigma_m = sigma;
        row.method = m;
        row.trials = p.trials;
        const TrialErrors te = run_kcr_trials(p, truth, exact, arc, sigma, row);
        summarise_kcr(te, m == Method::kKnownRadius ? known_bound : free_bound, row);
        rows.push_back(row);
      }
    }
  }
  return rows;
}

std::string kcr_csv(const std::vector<KcrRow>& rows) {
  std::string s =
      "arc_deg,sigma_m,method,trials,failed,kcr_sd_cx,kcr_sd_cy,kcr_sd_r,rmse_cx,rmse_cy,rmse_r,spread_cx,spread_cy,"
      "spread_r,bias_cx,bias_cy,bias_r,ratio_cx,ratio_cy,ratio_r,reported_ratio_cx,reported_ratio_cy,reported_ratio_"
      "r\n";
  for (const auto& r : rows) {
    s += fmt::format("{},{},{},{},{}", r.arc_deg, r.sigma_m, to_string(r.method), r.trials, r.failed);
    for (const auto* v : {r.kcr_sd, r.rmse, r.spread, r.bias, r.ratio, r.reported_sd_ratio})
      for (int k = 0; k < 3; ++k) s += fmt::format(",{:.6g}", v[k]);
    s += "\n";
  }
  return s;
}

// ---------------------------------------------------------------------------- second order

namespace {

/// The geometric fit polished to rounding precision (Gauss-Newton from
/// `start` until the step vanishes): its Taylor coefficients are read off
/// differences of such fits, which LM's stopping tolerance would blur.
Eigen::Vector3d geometric_exact(const Eigen::Matrix2Xd& pts, Eigen::Vector3d t) {
  for (int it = 0; it < 200; ++it) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (Eigen::Index i = 0; i < pts.cols(); ++i) {
      const Eigen::Vector2d dv = pts.col(i) - t.head<2>();
      const double rho = dv.norm();
      const Eigen::Vector3d J(-dv.x() / rho, -dv.y() / rho, -1.0);
      H.noalias() += J * J.transpose();
      g += J * (rho - t(2));
    }
    const Eigen::Vector3d step = -H.ldlt().solve(g);
    t += step;
    if (step.norm() < 1e-16) break;
  }
  return t;
}

/// The best the kcr_study metric can get from shifting every estimate by one
/// constant (any bias correction): 1.4826 x half the shortest interval that
/// holds half of the errors (for a Gaussian, its SD).
double shorth_rms(std::vector<double> e) {
  if (e.size() < 2) return std::nan("");
  std::sort(e.begin(), e.end());
  const std::size_t h = (e.size() + 1) / 2;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + h - 1 < e.size(); ++i) best = std::min(best, e[i + h - 1] - e[i]);
  return 1.4826 * 0.5 * best;
}

/// The geometric fit refitted with the arc's ends weighted down, w = 1 -
/// 0.5 s^2 (s: a point's angle about the fitted centre from the middle of
/// the arc, over the half-span). Not first-order efficient, but it trades a
/// little of the first-order variance for less of the second-order
/// normal-times-tangential term, which is larger at the ends of a short arc.
/// The shape was chosen on other draws (seed 5) than the study's.
CircleFit end_weighted_fit(const Eigen::Matrix2Xd& pts) {
  const CircleFit f = fit_circle(pts);
  if (!f.ok()) return f;
  Eigen::Vector2d m = Eigen::Vector2d::Zero();
  for (Eigen::Index i = 0; i < pts.cols(); ++i) m += (pts.col(i) - f.circle.centre_m).normalized();
  const double mid = std::atan2(m.y(), m.x());
  std::vector<double> ang(static_cast<std::size_t>(pts.cols()));
  double half = 0.0;
  for (Eigen::Index i = 0; i < pts.cols(); ++i) {
    const Eigen::Vector2d d = pts.col(i) - f.circle.centre_m;
    ang[static_cast<std::size_t>(i)] = std::remainder(std::atan2(d.y(), d.x()) - mid, 2 * kPi);
    half = std::max(half, std::abs(ang[static_cast<std::size_t>(i)]));
  }
  std::vector<double> sd(ang.size());
  for (std::size_t i = 0; i < ang.size(); ++i) {
    const double s = ang[i] / half;
    sd[i] = 1.0 / std::sqrt(std::max(0.05, 1.0 - 0.5 * s * s));
  }
  return refine_circle(pts, f.circle, {}, sd);
}

}  // namespace

namespace {

constexpr int kNodes = 9;  // s = -4h..4h, a degree-8 polynomial through them
const char* const kSecondOrderMethods[] = {"geometric", "hyper", "end_weighted", "geometric_second_order"};

/// a1, a2, a3 (columns) of the fit of exact + s e, from fits at s = -4h..4h
/// continued outwards from the truth.
class TaylorExpansion {
 public:
  TaylorExpansion(const Eigen::Vector3d& theta0, double step_m) : theta0_(theta0), step_m_(step_m) {
    Eigen::Matrix<double, kNodes, kNodes> V;
    for (int j = 0; j < kNodes; ++j)
      for (int k = 0; k < kNodes; ++k) V(j, k) = std::pow(static_cast<double>(j - 4), k);
    Vinv_ = V.fullPivLu().inverse();
  }

  Eigen::Matrix3d operator()(const Eigen::Matrix2Xd& exact, const Eigen::Matrix2Xd& e, bool geo) const {
    Eigen::Matrix<double, kNodes, 3> th;
    for (const int dir : {1, -1}) {
      Eigen::Vector3d prev = theta0_;
      for (int j = 0; j <= 4; ++j) {
        const Eigen::Matrix2Xd q = exact + (dir * j * step_m_) * e;
        if (geo) {
          prev = geometric_exact(q, prev);
        } else {
          const CircleFit h = fit_circle_hyper(q);
          prev = Eigen::Vector3d(h.circle.centre_m.x(), h.circle.centre_m.y(), h.circle.radius_m);
        }
        th.row(4 + dir * j) = prev.transpose();
      }
    }
    const Eigen::Matrix<double, kNodes, 3> c = Vinv_ * th;
    Eigen::Matrix3d a;
    for (int k = 1; k <= 3; ++k) a.col(k - 1) = c.row(k).transpose() / std::pow(step_m_, k);
    return a;
  }

 private:
  Eigen::Vector3d theta0_;
  double step_m_;
  Eigen::Matrix<double, kNodes, kNodes> Vinv_;
};

/// What one method's draws leave: the Taylor coefficients per draw (when
/// expanded), the a2 parts' second moments, and the errors at every sigma.
struct SecondOrderDraws {
  std::vector<Eigen::Matrix3d> coef;           // columns a1 a2 a3
  std::vector<Eigen::Vector3d> cross_of_draw;  // the normal x tangential part of a2
  std::vector<std::vector<Eigen::Vector3d>> err;
  Eigen::Vector3d En2 = Eigen::Vector3d::Zero(), Et2 = En2, Ex2 = En2;  // E[a2^2] of the normal, tangential, cross
};

/// Expectations of the Taylor coefficients over the draws.
struct SecondOrderMoments {
  Eigen::Vector3d Ea1sq = Eigen::Vector3d::Zero(), Ea2sq = Ea1sq, Ea1a3 = Ea1sq, Ea2 = Ea1sq, En2, Et2, Ex2;
};

CircleFit second_order_fit(int m, const Eigen::Matrix2Xd& q) {
  switch (m) {
    case 0: return fit_circle(q);
    case 1: return fit_circle_hyper(q);
    case 2: return end_weighted_fit(q);
    default: return fit_circle(q, second_order_params());
  }
}

/// The second-order term split by the noise's normal and tangential parts
/// (at the true points): a2(e) = a2(n) + a2(t) + cross.
void expand_draw(const TaylorExpansion& taylor, const Circle& truth, const Eigen::Matrix2Xd& exact,
                 const Eigen::Matrix2Xd& e, bool geo, SecondOrderDraws& d) {
  const Eigen::Matrix3d a = taylor(exact, e, geo);
  Eigen::Matrix2Xd en(2, e.cols()), et(2, e.cols());
  for (Eigen::Index i = 0; i < e.cols(); ++i) {
    const Eigen::Vector2d u = (exact.col(i) - truth.centre_m).normalized();
    en.col(i) = u * u.dot(e.col(i));
    et.col(i) = e.col(i) - en.col(i);
  }
  const Eigen::Vector3d a2n = taylor(exact, en, geo).col(1), a2t = taylor(exact, et, geo).col(1);
  const Eigen::Vector3d cross = a.col(1) - a2n - a2t;
  d.En2 += a2n.cwiseProduct(a2n);
  d.Et2 += a2t.cwiseProduct(a2t);
  d.Ex2 += cross.cwiseProduct(cross);
  d.coef.push_back(a);
  d.cross_of_draw.push_back(cross);
}

/// Method m's draws at one arc: the Taylor series of the two smooth fits
/// (m < 2), the weighted one by Monte-Carlo only.
SecondOrderDraws run_second_order_draws(const SecondOrderParams& p, const TaylorExpansion& taylor, const Circle& truth,
                                        const Eigen::Matrix2Xd& exact, double arc, int m) {
  const Eigen::Vector3d theta0(truth.centre_m.x(), truth.centre_m.y(), truth.radius_m);
  SecondOrderDraws d;
  d.err.resize(p.sigmas_m.size());
  common::SplitMixRandom rng(p.seed + static_cast<std::uint64_t>(arc * 1000));
  Eigen::Matrix2Xd e(2, p.points);
  for (int t = 0; t < p.draws; ++t) {
    for (int i = 0; i < p.points; ++i) e.col(i) = Eigen::Vector2d(rng.normal(), rng.normal());
    if (m < 2) expand_draw(taylor, truth, exact, e, m == 0, d);
    for (std::size_t si = 0; si < p.sigmas_m.size(); ++si) {
      const CircleFit f = second_order_fit(m, exact + p.sigmas_m[si] * e);
      Eigen::Vector3d dv = Eigen::Vector3d::Constant(std::nan(""));
      if (f.ok()) dv = Eigen::Vector3d(f.circle.centre_m.x(), f.circle.centre_m.y(), f.circle.radius_m) - theta0;
      d.err[si].push_back(dv);
    }
  }
  return d;
}

SecondOrderMoments moments(const SecondOrderDraws& d) {
  SecondOrderMoments mo;
  for (const auto& a : d.coef) {
    mo.Ea1sq += a.col(0).cwiseProduct(a.col(0));
    mo.Ea2sq += a.col(1).cwiseProduct(a.col(1));
    mo.Ea1a3 += a.col(0).cwiseProduct(a.col(2));
    mo.Ea2 += a.col(1);
  }
  const double nd = std::max<double>(1.0, static_cast<double>(d.coef.size()));
  mo.Ea1sq /= nd;
  mo.Ea2sq /= nd;
  mo.Ea1a3 /= nd;
  mo.Ea2 /= nd;
  mo.En2 = d.En2 / nd;
  mo.Et2 = d.Et2 / nd;
  mo.Ex2 = d.Ex2 / nd;
  return mo;
}

/// The series' terms of component k at noise s, over the bound's SD.
void series_terms(const SecondOrderMoments& mo, double s, double kcr, int k, SecondOrderRow& row) {
  const double kcr2 = kcr * kcr;
  const double first = s * s * mo.Ea1sq(k);
  const double s4 = s * s * s * s;
  row.first_order[k] = std::sqrt(first) / kcr;
  row.second_order[k] = std::sqrt(std::max(0.0, first + s4 * (mo.Ea2sq(k) + 2.0 * mo.Ea1a3(k)))) / kcr;
  row.mse_terms[k][0] = s4 * mo.Ea2sq(k) / kcr2;
  row.mse_terms[k][1] = 2.0 * s4 * mo.Ea1a3(k) / kcr2;
  row.mse_terms[k][2] = s4 * mo.Ea2(k) * mo.Ea2(k) / kcr2;
  row.bias2[k] = s * s * mo.Ea2(k) / kcr;
  row.a2_split[k][0] = s4 * mo.En2(k) / kcr2;
  row.a2_split[k][1] = s4 * mo.Et2(k) / kcr2;
  row.a2_split[k][2] = s4 * mo.Ex2(k) / kcr2;
}

/// The Monte-Carlo errors of component k at sigma index si, and the
/// truncated series' errors of the same draws, over the bound's SD.
void monte_carlo_terms(const SecondOrderDraws& d, std::size_t si, double s, double kcr, int k, SecondOrderRow& row) {
  std::vector<double> full, s2, s3, forced;
  double sum = 0, sumsq = 0;
  int n = 0;
  for (std::size_t t = 0; t < d.err[si].size(); ++t) {
    if (t < d.coef.size()) {
      const double y2 = s * d.coef[t](k, 0) + s * s * d.coef[t](k, 1);
      s2.push_back(y2);
      s3.push_back(y2 + s * s * s * d.coef[t](k, 2));
      forced.push_back(s * d.coef[t](k, 0) + s * s * d.cross_of_draw[t](k));
    }
    const double x = d.err[si][t](k);
    if (std::isnan(x)) continue;
    full.push_back(x);
    sum += x;
    sumsq += x * x;
    ++n;
  }
  row.mc_rms[k] = n ? std::sqrt(sumsq / n) / kcr : std::nan("");
  row.mc_mean_bias[k] = n ? sum / n / kcr : std::nan("");
  row.mc_robust[k] = robust_rms(full) / kcr;
  row.mc_shorth[k] = shorth_rms(full) / kcr;
  row.series2_robust[k] = robust_rms(s2) / kcr;
  row.series3_robust[k] = robust_rms(s3) / kcr;
  row.forced_robust[k] = robust_rms(forced) / kcr;
  row.forced_shorth[k] = shorth_rms(forced) / kcr;
}

/// The series' columns mean nothing for a method that was not expanded.
void blank_series(int k, SecondOrderRow& row) {
  for (double* v : {&row.first_order[k], &row.second_order[k], &row.mse_terms[k][0], &row.mse_terms[k][1],
                    &row.mse_terms[k][2], &row.a2_split[k][0], &row.a2_split[k][1], &row.a2_split[k][2], &row.bias2[k],
                    &row.series2_robust[k], &row.series3_robust[k], &row.forced_robust[k], &row.forced_shorth[k]})
    *v = std::nan("");
}

SecondOrderRow second_order_row(const SecondOrderParams& p, const SecondOrderDraws& d, const SecondOrderMoments& mo,
                                const KcrBound& b, double arc, int m, std::size_t si) {
  const double s = p.sigmas_m[si];
  SecondOrderRow row;
  row.arc_deg = arc;
  row.sigma_m = s;
  row.method = kSecondOrderMethods[m];
  row.draws = p.draws;
  for (int k = 0; k < 3; ++k) {
    const double kcr = std::sqrt(b.covariance(k, k));
    row.kcr_sd[k] = kcr;
    series_terms(mo, s, kcr, k, row);
    monte_carlo_terms(d, si, s, kcr, k, row);
    if (m >= 2) blank_series(k, row);
  }
  return row;
}

}  // namespace

std::vector<SecondOrderRow> second_order_study(const SecondOrderParams& p) {
  std::vector<SecondOrderRow> rows;
  const Circle truth{{0.0, 0.0}, p.radius_m};
  const TaylorExpansion taylor(Eigen::Vector3d(truth.centre_m.x(), truth.centre_m.y(), truth.radius_m), p.step_m);
  for (const double arc : p.arcs_deg) {
    const Eigen::Matrix2Xd exact = arc_points(truth, arc, p.points);
    for (int m = 0; m < 4; ++m) {
      const SecondOrderDraws d = run_second_order_draws(p, taylor, truth, exact, arc, m);
      const SecondOrderMoments mo = moments(d);
      for (std::size_t si = 0; si < p.sigmas_m.size(); ++si) {
        const std::vector<double> sig{p.sigmas_m[si]};
        rows.push_back(second_order_row(p, d, mo, kcr_bound(exact, truth, sig, false), arc, m, si));
      }
    }
  }
  return rows;
}

std::string second_order_csv(const std::vector<SecondOrderRow>& rows) {
  std::string s = "arc_deg,sigma_m,method,draws";
  for (const char* f : {"kcr_sd", "first_order", "second_order", "mse_a2sq", "mse_2a1a3", "mse_bias2", "a2sq_normal",
                        "a2sq_tangential", "a2sq_cross", "bias2", "mc_rms", "mc_mean_bias", "mc_robust", "mc_shorth",
                        "series2_robust", "series3_robust", "forced_robust", "forced_shorth"})
    for (const char* c : {"cx", "cy", "r"}) s += fmt::format(",{}_{}", f, c);
  s += "\n";
  for (const auto& r : rows) {
    s += fmt::format("{},{},{},{}", r.arc_deg, r.sigma_m, r.method, r.draws);
    for (int k = 0; k < 3; ++k) s += fmt::format(",{:.6g}", r.kcr_sd[k]);
    for (const auto* v : {r.first_order, r.second_order})
      for (int k = 0; k < 3; ++k) s += fmt::format(",{:.4f}", v[k]);
    for (int t = 0; t < 3; ++t)
      for (int k = 0; k < 3; ++k) s += fmt::format(",{:.4f}", r.mse_terms[k][t]);
    for (int t = 0; t < 3; ++t)
      for (int k = 0; k < 3; ++k) s += fmt::format(",{:.4f}", r.a2_split[k][t]);
    for (const auto* v : {r.bias2, r.mc_rms, r.mc_mean_bias, r.mc_robust, r.mc_shorth, r.series2_robust,
                          r.series3_robust, r.forced_robust, r.forced_shorth})
      for (int k = 0; k < 3; ++k) s += fmt::format(",{:.4f}", v[k]);
    s += "\n";
  }
  return s;
}

// ---------------------------------------------------------------------------- robustness

namespace {

/// One way of fitting the robustness study's scans.
struct RobustnessMethod {
  const char* name;
  bool robust, views, self_filter;
  double min_r, max_r;  // radius prior (multiples of the true radius); 0, 0: none
  bool known;
};
constexpr RobustnessMethod kRobustnessMethods[] = {{"plain", false, false, false, 0, 0, false},
                                                   {"msac", true, false, false, 0, 0, false},
                                                   {"msac_views", true, true, false, 0, 0, false},
                                                   {"msac_views_selffilter", true, true, true, 0, 0, false},
                                                   {"msac_views_radius_prior", true, true, false, 0.6, 1.5, false},
                                                   {"msac_views_known_radius", true, true, false, 0, 0, true}};

/// The target near `ring`, and `clutter` smaller objects inside the ring,
/// close to but clear of the target.
PlanarWorld cluttered_world(const Eigen::Vector2d& ring, double radius_m, int clutter, common::SplitMixRandom& rng) {
  PlanarWorld world;
  const Circle truth{ring + Eigen::Vector2d(0.04 * (rng.uniform() - 0.5), 0.04 * (rng.uniform() - 0.5)), radius_m};
  world.cylinders.push_back(truth);
  for (int c = 0; c < clutter; ++c) {
    for (int tries = 0; tries < 50; ++tries) {
      const double a = 2 * kPi * rng.uniform();
      const double d = radius_m + 0.06 + 0.08 * rng.uniform();
      const Circle o{truth.centre_m + d * Eigen::Vector2d(std::cos(a), std::sin(a)), 0.025 + 0.02 * rng.uniform()};
      bool clear = (o.centre_m - truth.centre_m).norm() > truth.radius_m + o.radius_m + 0.03;
      for (const auto& w : world.cylinders) clear = clear && (o.centre_m - w.centre_m).norm() > w.radius_m + o.radius_m;
      if (clear) {
        world.cylinders.push_back(o);
        break;
      }
    }
  }
  world.robot_links_visible = true;
  return world;
}

CircleEstimatorParams robustness_estimator(const RobustnessMethod& m, double radius_m, int t) {
  CircleEstimatorParams ep;
  ep.fusion.self_filter = m.self_filter;
  ep.use_viewpoints = m.views;
  ep.robust.max_radius_m = 0.5;
  if (m.max_r > 0) {
    ep.robust.min_radius_m = m.min_r * radius_m;
    ep.robust.max_radius_m = m.max_r * radius_m;
  }
  if (m.known) ep.robust.known_radius_m = radius_m;
  ep.robust.seed = static_cast<std::uint64_t>(t + 1);
  return ep;
}

/// Outlier share of what the fit is offered (self points included when the
/// self-filter is off).
double outlier_fraction(const FusedCloud& cloud, const Circle& truth) {
  int out = 0;
  for (int i = 0; i < cloud.size(); ++i) {
    const double d = std::abs((cloud.points_m().col(i) - truth.centre_m).norm() - truth.radius_m);
    out += d > 0.03;
  }
  return cloud.size() ? static_cast<double>(out) / cloud.size() : 0.0;
}

/// Scores one trial's fit into the row.
void score_robustness_trial(const CircleFit& fit, const Circle& truth, double outliers, RobustnessRow& row,
                            std::vector<double>& centre_err) {
  ++row.trials;
  const bool hard = outliers >= 0.4;
  row.trials_over_40 += hard;
  if (!fit.ok()) return;
  ++row.ok;
  const double ce = (fit.circle.centre_m - truth.centre_m).norm();
  centre_err.push_back(ce);
  if (ce < 0.01 && std::abs(fit.circle.radius_m - truth.radius_m) < 0.01) {
    ++row.correct;
    row.correct_over_40 += hard;
  }
}

RobustnessRow robustness_row(const RobustnessParams& p, const RobotModel& model, const std::vector<double>& joints,
                             const Eigen::Vector2d& ring, int clutter, const RobustnessMethod& m) {
  RobustnessRow row;
  row.method = m.name;
  row.clutter_objects = clutter;
  std::vector<double> centre_err, outlier_frac;
  common::SplitMixRandom rng(p.seed);
  JointStateBuffer jb(model.joint_names());
  (void)jb.add(0, model.joint_names(), joints);
  for (int t = 0; t < p.trials; ++t) {
    const PlanarWorld world = cluttered_world(ring, p.radius_m, clutter, rng);
    const Circle& truth = world.cylinders.front();
    const auto scans = scan_all(model, joints, world, {}, rng);
    CircleEstimator est(model, robustness_estimator(m, p.radius_m, t));
    std::vector<ScanView> views;
    for (const auto& s : scans) views.push_back({s.sensor, 0, s.angle_rad, s.range_m});
    CircleEstimate e = est.estimate(views, jb);
    const FusedCloud& cloud = est.cloud();
    outlier_frac.push_back(outlier_fraction(cloud, truth));
    if (!m.robust) {
      const std::span<const double> sig(cloud.sigma_m);
      e.fit = fit_circle(cloud.points_m(), {}, sig);
    }
    score_robustness_trial(e.fit, truth, outlier_frac.back(), row, centre_err);
  }
  row.median_centre_error_m = median(centre_err);
  row.median_outlier_fraction = median(outlier_frac);
  return row;
}

}  // namespace

std::vector<RobustnessRow> robustness_study(const RobustnessParams& p) {
  const RobotModel model = RobotModel::load(p.robot_description);
  const double q = p.joint_deg * kPi / 180.0;
  const std::vector<double> joints(model.joint_names().size(), q);
  // Centre of the ring the chain curls into (equal links, equal turns).
  const double L = model.links().front().length_m;
  const Eigen::Vector2d ring(0.5 * L, 0.5 * L / std::tan(0.5 * q));
  std::vector<RobustnessRow> rows;
  for (const int clutter : p.clutter_objects)
    for (const auto& m : kRobustnessMethods) rows.push_back(robustness_row(p, model, joints, ring, clutter, m));
  return rows;
}

std::string robustness_csv(const std::vector<RobustnessRow>& rows) {
  std::string s =
      "clutter_objects,method,trials,ok,correct,trials_over_40,correct_over_40,median_centre_error_m,"
      "median_outlier_fraction\n";
  for (const auto& r : rows)
    s += fmt::format("{},{},{},{},{},{},{},{:.6g},{:.4f}\n", r.clutter_objects, r.method, r.trials, r.ok, r.correct,
                     r.trials_over_40, r.correct_over_40, r.median_centre_error_m, r.median_outlier_fraction);
  return s;
}

// ---------------------------------------------------------------------------- ray noise

namespace {

/// The cylinder's true points as the sensors see it, each point's noise
/// along its surface normal, and the arc they cover [deg].
struct TruePoints {
  Eigen::Matrix2Xd points;
  std::vector<double> normal_sd;
  double arc_deg = 0;
};

/// Arc covered: 360 minus the largest gap between sorted point angles.
double covered_arc_deg(std::vector<double> angles) {
  std::sort(angles.begin(), angles.end());
  double gap = angles.empty() ? 2 * kPi : angles.front() + 2 * kPi - angles.back();
  for (std::size_t i = 1; i < angles.size(); ++i) gap = std::max(gap, angles[i] - angles[i - 1]);
  return (2 * kPi - gap) * 180.0 / kPi;
}

TruePoints true_points(const RobotModel& model, const std::vector<double>& joints, const PlanarWorld& world,
                       const Circle& truth) {
  SyntheticScanParams exact;
  exact.noise_scale = 0.0;
  common::SplitMixRandom rng0(1);
  const auto clean = scan_all(model, joints, world, exact, rng0);
  std::vector<Eigen::Vector2d> tp;
  std::vector<double> angles;
  TruePoints out;
  const Kinematics k = model.forward(joints);
  for (std::size_t s = 0; s < clean.size(); ++s) {
    const auto& T = k.T_base_sensor[s];
    for (std::size_t i = 0; i < clean[s].range_m.size(); ++i) {
      if (clean[s].hit_kind[i] != kHitCylinder) continue;
      const double r = clean[s].true_range_m[i];
      const Eigen::Vector2d ray = (T.linear() * model.sensors()[s].ray(clean[s].angle_rad[i])).normalized();
      const Eigen::Vector2d pt = T.translation() + r * ray;
      const Eigen::Vector2d nrm = (pt - truth.centre_m).normalized();
      tp.push_back(pt);
      out.normal_sd.push_back(SyntheticScanParams{}.noise.sd_at(r) * std::abs(ray.dot(nrm)));
      angles.push_back(std::atan2(nrm.y(), nrm.x()));
    }
  }
  out.arc_deg = covered_arc_deg(std::move(angles));
  out.points.resize(2, static_cast<Eigen::Index>(tp.size()));
  for (std::size_t i = 0; i < tp.size(); ++i) out.points.col(static_cast<Eigen::Index>(i)) = tp[i];
  return out;
}

/// One way of fitting the ray-noise study's scans.
struct RayNoiseVariant {
  const char* name;
  bool kasa, incidence, bias;
  ArcCorrection correction = ArcCorrection::kNone;
};
constexpr RayNoiseVariant kRayNoiseVariants[] = {{"kasa", true, false, false},
                                                 {"msac", false, false, false},
                                                 {"msac_incidence", false, true, false},
                                                 {"estimator_plain_refit", false, true, true},
                                                 {"estimator", false, true, true, ArcCorrection::kSecondOrder}};

/// What every variant's row of one pose shares: the settings, the robot, its world.
struct RayNoiseRun {
  const RayNoiseParams& p;
  const RobotModel& model;
  const std::vector<double>& joints;
  const PlanarWorld& world;
  const Circle& truth;
};

RayNoiseRow ray_noise_row(const RayNoiseRun& run, const TruePoints& tp, const KcrBound& b, double jd, double scale,
                          const RayNoiseVariant& v) {
  const RayNoiseParams& p = run.p;
  RayNoiseRow row;
  row.joint_deg = jd;
  row.noise_scale = scale;
  row.variant = v.name;
  row.points = static_cast<int>(tp.normal_sd.size());
  row.arc_deg = tp.arc_deg;
  row.trials = p.trials;
  common::SplitMixRandom rng(p.seed + static_cast<std::uint64_t>(jd * 100 + scale * 10));
  SyntheticScanParams noisy;
  noisy.noise_scale = scale;
  CircleEstimatorParams ep;
  ep.incidence_weighting = v.incidence;
  ep.remove_radius_bias = v.bias;
  ep.arc_correction = v.correction;
  ep.robust.inlier_threshold_m = 0.1;  // no outliers here: keep every point
  CircleEstimator est(run.model, ep);
  JointStateBuffer jb(run.model.joint_names());
  (void)jb.add(0, run.model.joint_names(), run.joints);
  std::vector<double> err[3];
  for (int t = 0; t < p.trials; ++t) {
    const auto scans = scan_all(run.model, run.joints, run.world, noisy, rng);
    std::vector<ScanView> views;
    for (const auto& sc : scans) views.push_back({sc.sensor, 0, sc.angle_rad, sc.range_m});
    CircleEstimate e = est.estimate(views, jb);
    if (v.kasa) e.fit = fit_circle_kasa(est.cloud().points_m());
    if (!e.fit.ok()) {
      ++row.failed;
      continue;
    }
    err[0].push_back(e.fit.circle.centre_m.x() - run.truth.centre_m.x());
    err[1].push_back(e.fit.circle.centre_m.y() - run.truth.centre_m.y());
    err[2].push_back(e.fit.circle.radius_m - run.truth.radius_m);
  }
  for (int c = 0; c < 3; ++c) {
    row.kcr_sd[c] = b.status.ok() ? std::sqrt(b.covariance(c, c)) : std::nan("");
    row.rmse[c] = robust_rms(err[c]);
    row.bias[c] = median(err[c]);
    row.ratio[c] = row.rmse[c] / row.kcr_sd[c];
  }
  return row;
}

}  // namespace

std::vector<RayNoiseRow> ray_noise_study(const RayNoiseParams& p) {
  const RobotModel model = RobotModel::load(p.robot_description);
  const double L = model.links().front().length_m;
  std::vector<RayNoiseRow> rows;
  for (const double jd : p.joint_deg) {
    const double q = jd * kPi / 180.0;
    const std::vector<double> joints(model.joint_names().size(), q);
    // The ring's centre; for an open chain the cylinder sits where the
    // middle sensors' axes meet it.
    const Circle truth{Eigen::Vector2d(0.5 * L, 0.5 * L / std::tan(0.5 * q)), p.radius_m};
    PlanarWorld world;
    world.cylinders.push_back(truth);
    world.robot_links_visible = false;
    const TruePoints tp = true_points(model, joints, world, truth);
    const RayNoiseRun run{p, model, joints, world, truth};
    for (const double scale : p.noise_scale) {
      std::vector<double> sns;
      for (const double x : tp.normal_sd) sns.push_back(scale * x);
      const KcrBound b = kcr_bound(tp.points, truth, sns);
      for (const auto& v : kRayNoiseVariants) rows.push_back(ray_noise_row(run, tp, b, jd, scale, v));
    }
  }
  return rows;
}

std::string ray_noise_csv(const std::vector<RayNoiseRow>& rows) {
  std::string s =
      "joint_deg,noise_scale,variant,points,arc_deg,trials,failed,kcr_sd_cx,kcr_sd_cy,kcr_sd_r,rmse_cx,rmse_cy,rmse_r,"
      "bias_cx,bias_cy,bias_r,ratio_cx,ratio_cy,ratio_r\n";
  for (const auto& r : rows) {
    s += fmt::format("{},{},{},{},{:.1f},{},{}", r.joint_deg, r.noise_scale, r.variant, r.points, r.arc_deg, r.trials,
                     r.failed);
    for (const auto* v : {r.kcr_sd, r.rmse, r.bias, r.ratio})
      for (int k = 0; k < 3; ++k) s += fmt::format(",{:.6g}", v[k]);
    s += "\n";
  }
  return s;
}

}  // namespace tinyline::hydrus_fitting::eval
