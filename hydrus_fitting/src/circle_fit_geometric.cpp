// SPDX-License-Identifier: Apache-2.0
// The geometric (maximum-likelihood) circle fit: Levenberg-Marquardt over
// the centre and radius, its covariance, and the essential bias removed.
#include "hydrus_fitting/circle_fit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <fmt/format.h>

#include <tinyline/common/least_squares.hpp>
#include <tinyline/common/random.hpp>

#include "circle_fit_internal.hpp"

namespace tinyline::hydrus_fitting {

using namespace detail;

common::Status validate(const RefineParams& params) {
  if (params.known_radius_m && !(*params.known_radius_m > 0.0 && std::isfinite(*params.known_radius_m)))
    return common::Status::invalid(
        fmt::format("known_radius_m must be finite and > 0, got {}", *params.known_radius_m));
  if (params.max_iterations < 1)
    return common::Status::invalid(fmt::format("max_iterations must be >= 1, got {}", params.max_iterations));
  if (params.correction == ArcCorrection::kSecondOrder) return validate_second_order(params.second_order);
  return common::Status{};
}

namespace {

// The geometric fit as a least-squares problem over (centre, radius), or
// over the centre alone when the radius is known (D = 2). `evaluate` gives,
// in one pass over the points, the cost and the normal equations at a full
// (cx, cy, r); `at` is the pass at the current circle.
template <int D, class Evaluate, class Pass>
struct GeometricCircleProblem {
  using Vector = Eigen::Matrix<double, D, 1>;
  Evaluate& evaluate;
  Pass& at;
  double known_radius_m;
  Pass pending;

  Eigen::Vector3d circle(const Vector& x) const {
    if constexpr (D == 3) {
      return x;
    } else {
      return {x(0), x(1), known_radius_m};
    }
  }
  std::pair<Eigen::Matrix<double, D, D>, Vector> linearise(const Vector&) const {
    return {at.H.template topLeftCorner<D, D>(), at.g.template head<D>()};
  }
  // The candidate's gradient system comes in the same pass as its cost: near
  // the minimum almost every step is accepted.
  double cost(Vector& candidate) {
    const Eigen::Vector3d t = circle(candidate);
    if (!(t(2) > 0.0)) return std::numeric_limits<double>::infinity();
    pending = evaluate(t);
    return pending.cost;
  }
  void accept() { at = pending; }
  bool converged(double old_cost, double new_cost, const Vector&) const {
    return old_cost - new_cost <= 1e-15 * old_cost;
  }
};

template <int D, class Evaluate, class Pass>
common::LevenbergMarquardtResult minimise_geometric(Evaluate& evaluate, Pass& at, Eigen::Vector3d& t,
                                                    const RefineParams& params) {
  common::LevenbergMarquardtSettings s;
  s.max_iterations = params.max_iterations;
  s.max_tries = 20;
  s.initial_lambda = params.initial_lambda;
  s.increase = 10.0;
  s.decrease = 0.1;
  s.min_lambda = 1e-12;
  // A step under the tolerance is not worth a pass over the points: its
  // cost differs from the current one at rounding level, so the test would
  // reject it about half the time and grow the damping for nothing.
  s.min_step = params.step_tolerance_m;
  s.accept_equal_cost = true;
  GeometricCircleProblem<D, Evaluate, Pass> problem{evaluate, at, t(2), {}};
  Eigen::Matrix<double, D, 1> x = t.template head<D>();
  const common::LevenbergMarquardtResult r = common::levenberg_marquardt(problem, x, at.cost, s);
  t.template head<D>() = x;
  return r;
}

}  // namespace

namespace {

/// The points refine_circle uses (finite, with a finite positive sigma) and
/// their weights, contiguous: every LM pass reads them.
struct UsedPoints {
  std::vector<double> buf;
  double* px = nullptr;
  double* py = nullptr;
  double* pw = nullptr;
  int n = 0;
  int non_finite = 0;
};

UsedPoints used_points(const Eigen::Ref<const Eigen::Matrix2Xd>& points, std::span<const double> sigma_m) {
  std::vector<Eigen::Index> idx;
  idx.reserve(static_cast<std::size_t>(points.cols()));
  UsedPoints u;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const bool ok_sigma = sigma_m.empty() || (std::isfinite(sigma_m[static_cast<std::size_t>(i)]) &&
                                              sigma_m[static_cast<std::size_t>(i)] > 0.0);
    if (finite(points.col(i)) && ok_sigma) {
      idx.push_back(i);
    } else {
      ++u.non_finite;
    }
  }
  u.n = static_cast<int>(idx.size());
  u.buf.resize(3 * static_cast<std::size_t>(u.n));
  u.px = u.buf.data();
  u.py = u.px + u.n;
  u.pw = u.py + u.n;
  for (int k = 0; k < u.n; ++k) {
    const Eigen::Index i = idx[static_cast<std::size_t>(k)];
    u.px[k] = points(0, i);
    u.py[k] = points(1, i);
    const double s = sigma_m.empty() ? 0.0 : sigma_m[static_cast<std::size_t>(i)];
    u.pw[k] = sigma_m.empty() ? 1.0 : 1.0 / (s * s);
  }
  return u;
}

/// Cost, gradient system (J^T W J, J^T W d) and the unweighted residual sum
/// of squares at a circle t, in one pass; J_i = -(u_x, u_y, 1), u the unit
/// vector from the centre to the point.
struct Pass {
  double cost = 0.0, rss = 0.0;
  Eigen::Matrix3d H;
  Eigen::Vector3d g;
};

/// The pass over the used points (their current weights). Two points per
/// step in SIMD lanes (each lane sums its own points; the lanes are added at
/// the end). A point at the centre has u = 0: dx = dy = 0 times a finite inverse.
struct EvaluatePass {
  const UsedPoints& pts;

  Pass operator()(const Eigen::Vector3d& t) const {
    using A2 = Eigen::Array2d;
    const double cx = t(0), cy = t(1), r = t(2);
    const int n = pts.n;
    const double* px = pts.px;
    const double* py = pts.py;
    const double* pw = pts.pw;
    A2 cost = A2::Zero(), rss = A2::Zero(), hxx = A2::Zero(), hxy = A2::Zero(), hyy = A2::Zero(), hxr = A2::Zero(),
       hyr = A2::Zero(), hrr = A2::Zero(), gx = A2::Zero(), gy = A2::Zero(), gr = A2::Zero();
    const auto point = [&](const auto& dx, const auto& dy, const auto& w, const auto& rho) {
      const auto d = (rho - r).eval();
      const auto inv = rho.max(std::numeric_limits<double>::min()).inverse().eval();
      const auto ux = (dx * inv).eval(), uy = (dy * inv).eval();
      const auto wd = (w * d).eval(), wux = (w * ux).eval(), wuy = (w * uy).eval();
      cost += wd * d;
      rss += d * d;
      hxx += wux * ux;
      hxy += wux * uy;
      hyy += wuy * uy;
      hxr += wux;
      hyr += wuy;
      hrr += w;
      gx -= wd * ux;
      gy -= wd * uy;
      gr -= wd;
    };
    int k = 0;
    for (; k + 1 < n; k += 2) {
      const A2 dx = A2::Map(px + k) - cx, dy = A2::Map(py + k) - cy;
      point(dx, dy, A2::Map(pw + k), (dx * dx + dy * dy).sqrt().eval());
    }
    if (k < n) {  // the odd point, in lane 0 (lane 1 adds zeros)
      const A2 dx(px[k] - cx, 0.0), dy(py[k] - cy, 0.0), w(pw[k], 0.0);
      const A2 rho((dx * dx + dy * dy).sqrt()(0), r);
      point(dx, dy, w, rho);
    }
    Pass out;
    out.cost = cost.sum();
    out.rss = rss.sum();
    out.H << hxx.sum(), hxy.sum(), hxr.sum(), hxy.sum(), hyy.sum(), hyr.sum(), hxr.sum(), hyr.sum(), hrr.sum();
    out.g << gx.sum(), gy.sum(), gr.sum();
    return out;
  }
};

/// Levenberg-Marquardt from t with the points' current weights; `at` ends
/// as the pass at the final t.
struct GeometricRun {
  EvaluatePass evaluate;
  const RefineParams& params;
  bool known = false;
  Pass at;
  bool converged = false;
  int iterations = 0;

  void operator()(Eigen::Vector3d& t) {
    at = evaluate(t);
    const common::LevenbergMarquardtResult r =
        known ? minimise_geometric<2>(evaluate, at, t, params) : minimise_geometric<3>(evaluate, at, t, params);
    converged = r.converged;
    iterations = r.iterations;
  }
};

/// The ML fit and its first-order covariance: (J^T W J)^-1, scaled by the
/// weighted residual variance when asked (or without sigmas).
CircleFit first_order_fit(const GeometricRun& run, const Eigen::Vector3d& theta, const UsedPoints& pts,
                          const RefineParams& params, bool sigmas_given) {
  const bool known = run.known;
  const int n = pts.n, p = known ? 2 : 3;
  CircleFit f;
  f.set_outcome(FitStatus::kOk);
  f.circle.centre_m = theta.head<2>();
  f.circle.radius_m = theta(2);
  f.points_used = n;
  f.non_finite = pts.non_finite;
  f.iterations = run.iterations;
  f.converged = run.converged;
  f.rms_residual_m = std::sqrt(run.at.rss / n);
  const bool use_residuals = params.covariance_from_residuals || !sigmas_given;
  const double dof = static_cast<double>(n - p);
  const double s2 = use_residuals ? (dof > 0 ? run.at.cost / dof : 0.0) : 1.0;
  if (known) {
    const Eigen::Matrix2d Hc = run.at.H.topLeftCorner<2, 2>();
    Eigen::FullPivLU<Eigen::Matrix2d> lu(Hc);
    if (lu.isInvertible()) f.covariance.topLeftCorner<2, 2>() = s2 * lu.inverse();
  } else {
    Eigen::FullPivLU<Eigen::Matrix3d> lu(run.at.H);
    if (lu.isInvertible()) f.covariance = s2 * lu.inverse();
  }
  return f;
}

/// Step 1 of the second-order correction: refit with the arc's ends weighted
/// down by the noise over the radius q seen in the residuals
/// (SecondOrderCorrection); changes the points' weights.
void weight_the_ends(CircleFit& f, GeometricRun& run, UsedPoints& pts, const Eigen::Vector3d& theta, double q,
                     const SecondOrderCorrection& so) {
  const double k_end = weight_the_arc_ends(f, pts.px, pts.py, pts.pw, pts.n, q, so);
  if (!(k_end > 0.0)) return;
  Eigen::Vector3d t2 = theta;
  run(t2);
  if (t2.allFinite() && t2(2) > 0.0) {
    f.circle.centre_m = t2.head<2>();
    f.circle.radius_m = t2(2);
    f.iterations += run.iterations;
    f.converged = f.converged && run.converged;
    f.rms_residual_m = std::sqrt(run.at.rss / pts.n);
    f.end_weight_applied = k_end;
  }
}

}  // namespace

CircleFit refine_circle(const Eigen::Ref<const Eigen::Matrix2Xd>& points, const Circle& initial,
                        const RefineParams& params, std::span<const double> sigma_m) {
  const bool known = params.known_radius_m.has_value();
  if (const common::Status v = validate(params); !v.ok()) return failed(FitStatus::kInvalidParams, v.message);
  if (!sigma_m.empty() && sigma_m.size() != static_cast<std::size_t>(points.cols())) {
    return failed(FitStatus::kInvalidParams,
                  fmt::format("sigma_m has {} entries for {} points", sigma_m.size(), points.cols()));
  }
  const int p = known ? 2 : 3;
  UsedPoints pts = used_points(points, sigma_m);
  const int n = pts.n;
  if (n < p) {
    return failed(FitStatus::kTooFewPoints, fmt::format("geometric fit needs at least {} finite points, got {}", p, n),
                  pts.non_finite);
  }
  if (!finite(initial.centre_m) || !std::isfinite(initial.radius_m)) {
    return failed(FitStatus::kInvalidParams, "initial circle is not finite", pts.non_finite);
  }
  Eigen::Vector3d theta(initial.centre_m.x(), initial.centre_m.y(), known ? *params.known_radius_m : initial.radius_m);
  GeometricRun run{EvaluatePass{pts}, params, known, {}, false, 0};
  run(theta);
  // The ML fit's first-order quantities, before any second-order refit:
  // the covariance and, for the essential bias, the weighted cost and sum.
  const double cost = run.at.cost;
  double wsum = 0.0;
  for (int k = 0; k < n; ++k) wsum += pts.pw[k];
  CircleFit f = first_order_fit(run, theta, pts, params, !sigma_m.empty());
  const double dof = static_cast<double>(n - p);
  const double q = dof > 0 ? std::sqrt(run.at.rss / dof) / f.circle.radius_m : 0.0;  // noise over radius, as seen
  if (params.correction == ArcCorrection::kSecondOrder && !known && n > p &&
      second_order_applies(params.second_order, n, q)) {
    f.second_order_applied = true;
    weight_the_ends(f, run, pts, theta, q, params.second_order);
    shift_to_the_mode(f, params.second_order);
  }
  if (params.remove_radius_bias && !known && n > p) {
    // Per point the tangential variance equals the normal one (isotropic):
    // s^2 sigma_i^2, s^2 the a-posteriori variance factor; the radius is
    // the weighted mean distance, so its bias is sum w s^2 sigma^2 / (2 r sum w).
    const double bias = (cost / dof) * n / (2.0 * f.circle.radius_m * wsum);
    if (std::isfinite(bias) && bias < 0.5 * f.circle.radius_m) {
      f.circle.radius_m -= bias;
      f.radius_bias_removed_m = bias;
    }
  }
  return f;
}

Eigen::Vector3d remove_essential_bias(const Eigen::Ref<const Eigen::Matrix2Xd>& points, CircleFit& fit,
                                      std::span<const double> sigma_m, std::span<const double> tangential_sd_m,
                                      std::span<const std::uint8_t> mask) {
  const auto n = static_cast<std::size_t>(points.cols());
  if (!fit.ok() || tangential_sd_m.size() != n || (!sigma_m.empty() && sigma_m.size() != n) ||
      (!mask.empty() && mask.size() != n) || !(fit.circle.radius_m > 0.0)) {
    return Eigen::Vector3d::Zero();
  }
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    if (!mask.empty() && !mask[i]) continue;
    const Eigen::Vector2d p = points.col(static_cast<Eigen::Index>(i));
    if (!finite(p) || !std::isfinite(tangential_sd_m[i])) continue;
    const double w = sigma_m.empty() ? 1.0 : 1.0 / (sigma_m[i] * sigma_m[i]);
    if (!std::isfinite(w)) continue;
    const Eigen::Vector2d dv = p - fit.circle.centre_m;
    const double rho = dv.norm();
    if (!(rho > 0.0)) continue;
    const Eigen::Vector3d j(-dv.x() / rho, -dv.y() / rho, -1.0);
    const double b = tangential_sd_m[i] * tangential_sd_m[i] / (2.0 * fit.circle.radius_m);
    H.noalias() += w * j * j.transpose();
    g += w * b * j;
  }
  Eigen::FullPivLU<Eigen::Matrix3d> lu(H);
  if (!lu.isInvertible()) return Eigen::Vector3d::Zero();
  // E[d] = b at the truth; the fit absorbed it as -H^-1 J^T W b: add it back.
  const Eigen::Vector3d shift = lu.solve(g);
  if (!shift.allFinite() || std::abs(shift(2)) > 0.5 * fit.circle.radius_m) return Eigen::Vector3d::Zero();
  fit.circle.centre_m += shift.head<2>();
  fit.circle.radius_m += shift(2);
  fit.radius_bias_removed_m -= shift(2);
  return shift;
}

CircleFit fit_circle(const Eigen::Ref<const Eigen::Matrix2Xd>& points, const RefineParams& params,
                     std::span<const double> sigma_m) {
  CircleFit init = fit_circle_hyper(points);
  if (!init.ok()) {
    if (params.known_radius_m && init.detail == FitStatus::kCollinear) {
      // A known radius still fixes a circle through collinear points (two
      // mirror solutions); the algebraic start cannot, so say so plainly.
      init.status.message += " (a known radius does not resolve which side the centre is on)";
    }
    return init;
  }
  CircleFit f = refine_circle(points, init.circle, params, sigma_m);
  return f;
}

}  // namespace tinyline::hydrus_fitting
