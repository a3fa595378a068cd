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
        // The same noise draws for every method (paired comparison).
        common::SplitMixRandom rng(p.seed + static_cast<std::uint64_t>(arc * 1000) +
                                   static_cast<std::uint64_t>(sigma * 1e7));
        std::vector<double> err[3], rep[3];
        KcrRow row;
        row.arc_deg = arc;
        row.sigma_m = sigma;
        row.method = m;
        row.trials = p.trials;
        Eigen::Matrix2Xd noisy(2, p.points);
        for (int t = 0; t < p.trials; ++t) {
          for (int i = 0; i < p.points; ++i) {
            noisy(0, i) = exact(0, i) + sigma * rng.normal();
            noisy(1, i) = exact(1, i) + sigma * rng.normal();
          }
          CircleFit f;
          switch (m) {
            case Method::kKasa: f = fit_circle_kasa(noisy); break;
            case Method::kHyper: f = fit_circle_hyper(noisy); break;
            case Method::kGeometric: f = fit_circle(noisy); break;
            case Method::kGeometricUnbiased: {
              RefineParams rp;
              rp.remove_radius_bias = true;
              f = fit_circle(noisy, rp);
              break;
            }
            case Method::kGeometricSecondOrder: f = fit_circle(noisy, second_order_params()); break;
            case Method::kRobust: {
              RobustCircleParams rp;
              rp.inlier_threshold_m = 4.0 * sigma;  // the node's rule: a few SDs of the range noise
              rp.max_radius_m = 100.0;
              rp.seed = static_cast<std::uint64_t>(t + 1);
              f = fit_circle_robust(noisy, rp);
              break;
            }
            case Method::kKnownRadius: {
              RefineParams rp;
              rp.known_radius_m = p.radius_m;
              const CircleFit h = fit_circle_hyper(noisy);
              f = refine_circle(noisy, h.ok() ? Circle{h.circle.centre_m, p.radius_m} : truth, rp);
              break;
            }
          }
          if (!f.ok()) {
            ++row.failed;
            continue;
          }
          const double e[3] = {f.circle.centre_m.x() - truth.centre_m.x(), f.circle.centre_m.y() - truth.centre_m.y(),
                               f.circle.radius_m - truth.radius_m};
          for (int k = 0; k < 3; ++k) {
            err[k].push_back(e[k]);
            rep[k].push_back(std::sqrt(std::max(0.0, f.covariance(k, k))));
          }
        }
        const KcrBound& b = (m == Method::kKnownRadius) ? known_bound : free_bound;
        for (int k = 0; k < 3; ++k) {
          if (m == Method::kKnownRadius && k == 2) continue;
          row.kcr_sd[k] = std::sqrt(b.covariance(k, k));
          std::vector<double> a;
          for (const double x : err[k]) a.push_back(std::abs(x));
          row.rmse[k] = 1.4826 * median(a);
          row.bias[k] = median(err[k]);
          std::vector<double> d;
          for (const double x : err[k]) d.push_back(std::abs(x - row.bias[k]));
          row.spread[k] = 1.4826 * median(d);
          row.ratio[k] = row.kcr_sd[k] > 0 ? row.rmse[k] / row.kcr_sd[k] : std::nan("");
          row.reported_sd_ratio[k] = row.kcr_sd[k] > 0 ? median(rep[k]) / row.kcr_sd[k] : std::nan("");
        }
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

double robust_rms(const std::vector<double>& e) {
  std::vector<double> a;
  a.reserve(e.size());
  for (const double x : e) a.push_back(std::abs(x));
  return 1.4826 * median(a);
}

}  // namespace

std::vector<SecondOrderRow> second_order_study(const SecondOrderParams& p) {
  std::vector<SecondOrderRow> rows;
  const Circle truth{{0.0, 0.0}, p.radius_m};
  const Eigen::Vector3d theta0(truth.centre_m.x(), truth.centre_m.y(), truth.radius_m);
  constexpr int kNodes = 9;  // s = -4h..4h, a degree-8 polynomial through them
  Eigen::Matrix<double, kNodes, kNodes> V;
  for (int j = 0; j < kNodes; ++j)
    for (int k = 0; k < kNodes; ++k) V(j, k) = std::pow(static_cast<double>(j - 4), k);
  const Eigen::Matrix<double, kNodes, kNodes> Vinv = V.fullPivLu().inverse();
  const char* methods[] = {"geometric", "hyper", "end_weighted", "geometric_second_order"};
  // a1, a2, a3 (columns) of the fit of exact + s e, from fits at s = -4h..4h
  // continued outwards from the truth.
  auto taylor = [&](const Eigen::Matrix2Xd& exact, const Eigen::Matrix2Xd& e, bool geo) {
    Eigen::Matrix<double, kNodes, 3> th;
    for (const int dir : {1, -1}) {
      Eigen::Vector3d prev = theta0;
      for (int j = 0; j <= 4; ++j) {
        const Eigen::Matrix2Xd q = exact + (dir * j * p.step_m) * e;
        if (geo) {
          prev = geometric_exact(q, prev);
        } else {
          const CircleFit h = fit_circle_hyper(q);
          prev = Eigen::Vector3d(h.circle.centre_m.x(), h.circle.centre_m.y(), h.circle.radius_m);
        }
        th.row(4 + dir * j) = prev.transpose();
      }
    }
    const Eigen::Matrix<double, kNodes, 3> c = Vinv * th;
    Eigen::Matrix3d a;
    for (int k = 1; k <= 3; ++k) a.col(k - 1) = c.row(k).transpose() / std::pow(p.step_m, k);
    return a;
  };
  for (const double arc : p.arcs_deg) {
    const Eigen::Matrix2Xd exact = arc_points(truth, arc, p.points);
    for (int m = 0; m < 4; ++m) {
      const bool geo = (m == 0);
      const bool expand = (m < 2);  // the Taylor series of the two smooth fits; the weighted one by Monte-Carlo only
      // Per draw: a1, a2, a3 (3 components each) and the estimator's error at every sigma.
      std::vector<Eigen::Matrix3d> coef;           // columns a1 a2 a3
      std::vector<Eigen::Vector3d> cross_of_draw;  // the normal x tangential part of a2
      std::vector<std::vector<Eigen::Vector3d>> err(p.sigmas_m.size());
      Eigen::Vector3d En2 = Eigen::Vector3d::Zero(), Et2 = En2,
                      Ex2 = En2;  // E[a2^2] of the normal, tangential, cross parts
      common::SplitMixRandom rng(p.seed + static_cast<std::uint64_t>(arc * 1000));
      Eigen::Matrix2Xd e(2, p.points), q(2, p.points);
      for (int t = 0; t < p.draws; ++t) {
        for (int i = 0; i < p.points; ++i) e.col(i) = Eigen::Vector2d(rng.normal(), rng.normal());
        if (expand) {
          const Eigen::Matrix3d a = taylor(exact, e, geo);
          // The second-order term split by the noise's normal and tangential
          // parts (at the true points): a2(e) = a2(n) + a2(t) + cross.
          Eigen::Matrix2Xd en(2, p.points), et(2, p.points);
          for (int i = 0; i < p.points; ++i) {
            const Eigen::Vector2d u = (exact.col(i) - truth.centre_m).normalized();
            en.col(i) = u * u.dot(e.col(i));
            et.col(i) = e.col(i) - en.col(i);
          }
          const Eigen::Vector3d a2n = taylor(exact, en, geo).col(1), a2t = taylor(exact, et, geo).col(1);
          const Eigen::Vector3d cross = a.col(1) - a2n - a2t;
          En2 += a2n.cwiseProduct(a2n);
          Et2 += a2t.cwiseProduct(a2t);
          Ex2 += cross.cwiseProduct(cross);
          coef.push_back(a);
          cross_of_draw.push_back(cross);
        }
        for (std::size_t si = 0; si < p.sigmas_m.size(); ++si) {
          q = exact + p.sigmas_m[si] * e;
          CircleFit f;
          switch (m) {
            case 0: f = fit_circle(q); break;
            case 1: f = fit_circle_hyper(q); break;
            case 2: f = end_weighted_fit(q); break;
            default: f = fit_circle(q, second_order_params()); break;
          }
          Eigen::Vector3d d = Eigen::Vector3d::Constant(std::nan(""));
          if (f.ok()) d = Eigen::Vector3d(f.circle.centre_m.x(), f.circle.centre_m.y(), f.circle.radius_m) - theta0;
          err[si].push_back(d);
        }
      }
      // Expectations over the draws.
      Eigen::Vector3d Ea1sq = Eigen::Vector3d::Zero(), Ea2sq = Ea1sq, Ea1a3 = Ea1sq, Ea2 = Ea1sq;
      for (const auto& a : coef) {
        Ea1sq += a.col(0).cwiseProduct(a.col(0));
        Ea2sq += a.col(1).cwiseProduct(a.col(1));
        Ea1a3 += a.col(0).cwiseProduct(a.col(2));
        Ea2 += a.col(1);
      }
      const double nd = std::max<double>(1.0, static_cast<double>(coef.size()));
      Ea1sq /= nd;
      Ea2sq /= nd;
      Ea1a3 /= nd;
      Ea2 /= nd;
      En2 /= nd;
      Et2 /= nd;
      Ex2 /= nd;
      for (std::size_t si = 0; si < p.sigmas_m.size(); ++si) {
        const double s = p.sigmas_m[si];
        const std::vector<double> sig{s};
        const KcrBound b = kcr_bound(exact, truth, sig, false);
        SecondOrderRow row;
        row.arc_deg = arc;
        row.sigma_m = s;
        row.method = methods[m];
        row.draws = p.draws;
        for (int k = 0; k < 3; ++k) {
          const double kcr = std::sqrt(b.covariance(k, k));
          const double kcr2 = kcr * kcr;
          row.kcr_sd[k] = kcr;
          const double first = s * s * Ea1sq(k);
          const double s4 = s * s * s * s;
          row.first_order[k] = std::sqrt(first) / kcr;
          row.second_order[k] = std::sqrt(std::max(0.0, first + s4 * (Ea2sq(k) + 2.0 * Ea1a3(k)))) / kcr;
          row.mse_terms[k][0] = s4 * Ea2sq(k) / kcr2;
          row.mse_terms[k][1] = 2.0 * s4 * Ea1a3(k) / kcr2;
          row.mse_terms[k][2] = s4 * Ea2(k) * Ea2(k) / kcr2;
          row.bias2[k] = s * s * Ea2(k) / kcr;
          row.a2_split[k][0] = s4 * En2(k) / kcr2;
          row.a2_split[k][1] = s4 * Et2(k) / kcr2;
          row.a2_split[k][2] = s4 * Ex2(k) / kcr2;
          std::vector<double> full, s2, s3, forced;
          double sum = 0, sumsq = 0;
          int n = 0;
          for (std::size_t t = 0; t < err[si].size(); ++t) {
            if (t < coef.size()) {
              const double y2 = s * coef[t](k, 0) + s * s * coef[t](k, 1);
              s2.push_back(y2);
              s3.push_back(y2 + s * s * s * coef[t](k, 2));
              forced.push_back(s * coef[t](k, 0) + s * s * cross_of_draw[t](k));
            }
            const double x = err[si][t](k);
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
          if (!expand) {
            for (double* v :
                 {&row.first_order[k], &row.second_order[k], &row.mse_terms[k][0], &row.mse_terms[k][1],
                  &row.mse_terms[k][2], &row.a2_split[k][0], &row.a2_split[k][1], &row.a2_split[k][2], &row.bias2[k],
                  &row.series2_robust[k], &row.series3_robust[k], &row.forced_robust[k], &row.forced_shorth[k]})
              *v = std::nan("");
          }
        }
        rows.push_back(row);
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

std::vector<RobustnessRow> robustness_study(const RobustnessParams& p) {
  const RobotModel model = RobotModel::load(p.robot_description);
  const double q = p.joint_deg * kPi / 180.0;
  const std::vector<double> joints(model.joint_names().size(), q);
  // Centre of the ring the chain curls into (equal links, equal turns).
  const double L = model.links().front().length_m;
  const Eigen::Vector2d ring(0.5 * L, 0.5 * L / std::tan(0.5 * q));

  struct M {
    const char* name;
    bool robust, views, self_filter;
    double min_r, max_r;  // radius prior (multiples of the true radius); 0, 0: none
    bool known;
  };
  const M methods[] = {{"plain", false, false, false, 0, 0, false},
                       {"msac", true, false, false, 0, 0, false},
                       {"msac_views", true, true, false, 0, 0, false},
                       {"msac_views_selffilter", true, true, true, 0, 0, false},
                       {"msac_views_radius_prior", true, true, false, 0.6, 1.5, false},
                       {"msac_views_known_radius", true, true, false, 0, 0, true}};
  std::vector<RobustnessRow> rows;
  for (const int clutter : p.clutter_objects) {
    for (const auto& m : methods) {
      RobustnessRow row;
      row.method = m.name;
      row.clutter_objects = clutter;
      std::vector<double> centre_err, outlier_frac;
      common::SplitMixRandom rng(p.seed);
      for (int t = 0; t < p.trials; ++t) {
        PlanarWorld world;
        const Circle truth{ring + Eigen::Vector2d(0.04 * (rng.uniform() - 0.5), 0.04 * (rng.uniform() - 0.5)),
                           p.radius_m};
        world.cylinders.push_back(truth);
        // Clutter: smaller objects inside the ring, close to but clear of the target.
        for (int c = 0; c < clutter; ++c) {
          for (int tries = 0; tries < 50; ++tries) {
            const double a = 2 * kPi * rng.uniform();
            const double d = p.radius_m + 0.06 + 0.08 * rng.uniform();
            const Circle o{truth.centre_m + d * Eigen::Vector2d(std::cos(a), std::sin(a)),
                           0.025 + 0.02 * rng.uniform()};
            bool clear = (o.centre_m - truth.centre_m).norm() > truth.radius_m + o.radius_m + 0.03;
            for (const auto& w : world.cylinders)
              clear = clear && (o.centre_m - w.centre_m).norm() > w.radius_m + o.radius_m;
            if (clear) {
              world.cylinders.push_back(o);
              break;
            }
          }
        }
        world.robot_links_visible = true;
        const auto scans = scan_all(model, joints, world, {}, rng);
        // Outlier share of what the fit is offered (self points included when
        // the self-filter is off).
        JointStateBuffer jb(model.joint_names());
        (void)jb.add(0, model.joint_names(), joints);
        CircleEstimatorParams ep;
        ep.fusion.self_filter = m.self_filter;
        ep.use_viewpoints = m.views;
        ep.robust.max_radius_m = 0.5;
        if (m.max_r > 0) {
          ep.robust.min_radius_m = m.min_r * p.radius_m;
          ep.robust.max_radius_m = m.max_r * p.radius_m;
        }
        if (m.known) ep.robust.known_radius_m = p.radius_m;
        ep.robust.seed = static_cast<std::uint64_t>(t + 1);
        CircleEstimator est(model, ep);
        std::vector<ScanView> views;
        for (const auto& s : scans) views.push_back({s.sensor, 0, s.angle_rad, s.range_m});
        CircleEstimate e = est.estimate(views, jb);
        const FusedCloud& cloud = est.cloud();
        int out = 0;
        for (int i = 0; i < cloud.size(); ++i) {
          const double d = std::abs((cloud.points_m().col(i) - truth.centre_m).norm() - truth.radius_m);
          out += d > 0.03;
        }
        outlier_frac.push_back(cloud.size() ? static_cast<double>(out) / cloud.size() : 0.0);
        if (!m.robust) {
          const std::span<const double> sig(cloud.sigma_m);
          e.fit = fit_circle(cloud.points_m(), {}, sig);
        }
        ++row.trials;
        const bool hard = outlier_frac.back() >= 0.4;
        row.trials_over_40 += hard;
        if (!e.fit.ok()) continue;
        ++row.ok;
        const double ce = (e.fit.circle.centre_m - truth.centre_m).norm();
        centre_err.push_back(ce);
        if (ce < 0.01 && std::abs(e.fit.circle.radius_m - truth.radius_m) < 0.01) {
          ++row.correct;
          row.correct_over_40 += hard;
        }
      }
      row.median_centre_error_m = median(centre_err);
      row.median_outlier_fraction = median(outlier_frac);
      rows.push_back(row);
    }
  }
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

std::vector<RayNoiseRow> ray_noise_study(const RayNoiseParams& p) {
  const RobotModel model = RobotModel::load(p.robot_description);
  const double L = model.links().front().length_m;
  std::vector<RayNoiseRow> rows;
  for (const double jd : p.joint_deg) {
    const double q = jd * kPi / 180.0;
    const std::vector<double> joints(model.joint_names().size(), q);
    // The ring's centre; for an open chain the cylinder sits where the
    // middle sensors' axes meet it.
    const Eigen::Vector2d ring(0.5 * L, 0.5 * L / std::tan(0.5 * q));
    const Circle truth{ring, p.radius_m};
    PlanarWorld world;
    world.cylinders.push_back(truth);
    world.robot_links_visible = false;
    SyntheticScanParams exact;
    exact.noise_scale = 0.0;
    common::SplitMixRandom rng0(1);
    const auto clean = scan_all(model, joints, world, exact, rng0);
    // True points, their normal noise and the arc they cover.
    std::vector<Eigen::Vector2d> tp;
    std::vector<double> sn;
    std::vector<double> angles;
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
        sn.push_back(SyntheticScanParams{}.noise.sd_at(r) * std::abs(ray.dot(nrm)));
        angles.push_back(std::atan2(nrm.y(), nrm.x()));
      }
    }
    // Arc covered: 360 minus the largest gap between sorted point angles.
    std::sort(angles.begin(), angles.end());
    double gap = angles.empty() ? 2 * kPi : angles.front() + 2 * kPi - angles.back();
    for (std::size_t i = 1; i < angles.size(); ++i) gap = std::max(gap, angles[i] - angles[i - 1]);
    const double arc = (2 * kPi - gap) * 180.0 / kPi;
    Eigen::Matrix2Xd tpm(2, static_cast<Eigen::Index>(tp.size()));
    for (std::size_t i = 0; i < tp.size(); ++i) tpm.col(static_cast<Eigen::Index>(i)) = tp[i];

    for (const double scale : p.noise_scale) {
      std::vector<double> sns;
      for (const double x : sn) sns.push_back(scale * x);
      const KcrBound b = kcr_bound(tpm, truth, sns);
      struct V {
        const char* name;
        bool kasa, incidence, bias;
        ArcCorrection correction = ArcCorrection::kNone;
      };
      for (const V v : {V{"kasa", true, false, false}, V{"msac", false, false, false},
                        V{"msac_incidence", false, true, false}, V{"estimator_plain_refit", false, true, true},
                        V{"estimator", false, true, true, ArcCorrection::kSecondOrder}}) {
        RayNoiseRow row;
        row.joint_deg = jd;
        row.noise_scale = scale;
        row.variant = v.name;
        row.points = static_cast<int>(tp.size());
        row.arc_deg = arc;
        row.trials = p.trials;
        common::SplitMixRandom rng(p.seed + static_cast<std::uint64_t>(jd * 100 + scale * 10));
        SyntheticScanParams noisy;
        noisy.noise_scale = scale;
        CircleEstimatorParams ep;
        ep.incidence_weighting = v.incidence;
        ep.remove_radius_bias = v.bias;
        ep.arc_correction = v.correction;
        ep.robust.inlier_threshold_m = 0.1;  // no outliers here: keep every point
        CircleEstimator est(model, ep);
        JointStateBuffer jb(model.joint_names());
        (void)jb.add(0, model.joint_names(), joints);
        std::vector<double> err[3];
        for (int t = 0; t < p.trials; ++t) {
          const auto scans = scan_all(model, joints, world, noisy, rng);
          std::vector<ScanView> views;
          for (const auto& sc : scans) views.push_back({sc.sensor, 0, sc.angle_rad, sc.range_m});
          CircleEstimate e = est.estimate(views, jb);
          if (v.kasa) e.fit = fit_circle_kasa(est.cloud().points_m());
          if (!e.fit.ok()) {
            ++row.failed;
            continue;
          }
          err[0].push_back(e.fit.circle.centre_m.x() - truth.centre_m.x());
          err[1].push_back(e.fit.circle.centre_m.y() - truth.centre_m.y());
          err[2].push_back(e.fit.circle.radius_m - truth.radius_m);
        }
        for (int c = 0; c < 3; ++c) {
          row.kcr_sd[c] = b.ok ? std::sqrt(b.covariance(c, c)) : std::nan("");
          std::vector<double> a;
          for (const double x : err[c]) a.push_back(std::abs(x));
          row.rmse[c] = 1.4826 * median(a);
          row.bias[c] = median(err[c]);
          row.ratio[c] = row.rmse[c] / row.kcr_sd[c];
        }
        rows.push_back(row);
      }
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
