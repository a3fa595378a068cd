// SPDX-License-Identifier: Apache-2.0
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

namespace tinyline::hydrus_fitting {

const char* to_string(FitStatus s) {
  switch (s) {
    case FitStatus::kOk: return "ok";
    case FitStatus::kTooFewPoints: return "too_few_points";
    case FitStatus::kCollinear: return "collinear";
    case FitStatus::kNoConsensus: return "no_consensus";
    case FitStatus::kRadiusOutOfRange: return "radius_out_of_range";
    case FitStatus::kInvalidParams: return "invalid_params";
  }
  return "unknown";
}

const char* to_string(ArcCorrection c) {
  switch (c) {
    case ArcCorrection::kNone: return "none";
    case ArcCorrection::kSecondOrder: return "second_order";
  }
  return "unknown";
}

namespace {

// Beyond this radius, in units of the points' RMS spread, a circle is a line
// for every practical purpose (and the algebraic solution is rounding noise).
constexpr double kLineRadiusRatio = 1e8;
// Points whose scatter has a smallest/largest eigenvalue ratio below this are
// a line: the eigenvalues carry ~1e-16 relative rounding, so anything much
// smaller cannot be told from zero (a 1 m line with 1 um of wiggle is a line).
constexpr double kCollinearPlanarity = 1e-12;

CircleFit failed(FitStatus s, std::string reason, int non_finite = 0) {
  CircleFit f;
  f.status = s;
  f.reason = std::move(reason);
  f.non_finite = non_finite;
  return f;
}

bool finite(const Eigen::Vector2d& p) { return std::isfinite(p.x()) && std::isfinite(p.y()); }

/// The finite points, centred on their mean and scaled to unit RMS distance,
/// so the algebraic fits' moment matrices are well conditioned.
struct Normalised {
  Eigen::Matrix2Xd q;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  double scale = 1.0;  // q = (p - mean) / scale
  int non_finite = 0;
};

/// Centres n.q (filled with finite points) on its mean, scales it to unit RMS distance.
void centre_and_scale(Normalised& n) {
  const auto k = n.q.cols();
  if (k == 0) return;
  n.mean = n.q.rowwise().mean();
  n.q.colwise() -= n.mean;
  const double ms = n.q.squaredNorm() / static_cast<double>(k);
  n.scale = ms > 0.0 ? std::sqrt(ms) : 1.0;
  n.q /= n.scale;
}

Normalised normalise(const Eigen::Ref<const Eigen::Matrix2Xd>& points) {
  Normalised n;
  n.q.resize(2, points.cols());
  Eigen::Index k = 0;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (finite(points.col(i))) {
      n.q.col(k++) = points.col(i);
    } else {
      ++n.non_finite;
    }
  }
  n.q.conservativeResize(2, k);
  centre_and_scale(n);
  return n;
}

/// Smallest over largest eigenvalue of the (normalised) scatter matrix: 0 for
/// points on a line, 1 for an isotropic spread.
double planarity(const Eigen::Matrix2Xd& q) {
  // Three sums: q q^T as a general product goes through the blocked GEMM
  // kernel, which costs more than the sums for a 2 x n matrix.
  Eigen::Matrix2d s;
  s(0, 0) = q.row(0).squaredNorm();
  s(1, 1) = q.row(1).squaredNorm();
  s(0, 1) = s(1, 0) = q.row(0).dot(q.row(1));
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(s, Eigen::EigenvaluesOnly);
  const double hi = es.eigenvalues()(1);
  return hi > 0.0 ? es.eigenvalues()(0) / hi : 0.0;
}

double rms_distance(const Eigen::Ref<const Eigen::Matrix2Xd>& points, const Circle& c) {
  double s = 0.0;
  int n = 0;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (!finite(points.col(i))) continue;
    const double d = (points.col(i) - c.centre_m).norm() - c.radius_m;
    s += d * d;
    ++n;
  }
  return n > 0 ? std::sqrt(s / n) : 0.0;
}

/// Circle from the algebraic parameters A (A0 z + A1 x + A2 y + A3 = 0) in
/// normalised coordinates, mapped back. Fails on a line (A0 ~ 0).
std::optional<Circle> circle_from_algebraic(const Eigen::Vector4d& A, const Normalised& n) {
  const double disc = A(1) * A(1) + A(2) * A(2) - 4.0 * A(0) * A(3);
  const double r_norm = std::sqrt(std::max(disc, 0.0)) / (2.0 * std::abs(A(0)));
  if (!std::isfinite(r_norm) || r_norm > kLineRadiusRatio || disc <= 0.0) return std::nullopt;
  return Circle{n.mean + n.scale * Eigen::Vector2d(-A(1) / (2.0 * A(0)), -A(2) / (2.0 * A(0))), n.scale * r_norm};
}

/// The same as a fit result, with the RMS distance of `points`.
CircleFit from_algebraic(const Eigen::Vector4d& A, const Normalised& n,
                         const Eigen::Ref<const Eigen::Matrix2Xd>& points, const char* method) {
  const auto circle = circle_from_algebraic(A, n);
  if (!circle) {
    return failed(FitStatus::kCollinear,
                  fmt::format("{} fit: the {} points are collinear (no finite circle fits them)", method, n.q.cols()),
                  n.non_finite);
  }
  CircleFit f;
  f.status = FitStatus::kOk;
  f.circle = *circle;
  f.points_used = static_cast<int>(n.q.cols());
  f.non_finite = n.non_finite;
  f.rms_residual_m = rms_distance(points, f.circle);
  return f;
}

/// Common checks of the algebraic fits: enough finite points, not all on a line.
std::optional<CircleFit> check_algebraic_input(const Normalised& n, const char* method) {
  const auto k = n.q.cols();
  if (k < 3) {
    return failed(FitStatus::kTooFewPoints,
                  fmt::format("{} fit needs at least 3 finite points, got {}{}", method, k,
                              n.non_finite ? fmt::format(" ({} non-finite skipped)", n.non_finite) : ""),
                  n.non_finite);
  }
  if (planarity(n.q) < kCollinearPlanarity) {
    return failed(FitStatus::kCollinear, fmt::format("{} fit: the {} points are collinear", method, k), n.non_finite);
  }
  return std::nullopt;
}

// Second-order correction: end weights below this are not worth a refit;
// no point's weight drops below this fraction.
constexpr double kMinEndWeight = 1e-3;
constexpr double kMinRelativeWeight = 0.05;

/// 1 up to `full`, 0 from `none`, linear between (a step when they are equal).
double fade(double x, double full, double none) {
  if (none > full) return std::clamp((none - x) / (none - full), 0.0, 1.0);
  return x < full ? 1.0 : 0.0;
}

common::Validation validate_second_order(const SecondOrderCorrection& so) {
  const auto bad = [](double v) { return !std::isfinite(v); };
  if (bad(so.end_weight) || so.end_weight < 0.0)
    return common::Validation::invalid(fmt::format("second_order.end_weight must be >= 0, got {}", so.end_weight));
  if (bad(so.max_end_weight) || so.max_end_weight < 0.0 || so.max_end_weight > 1.0)
    return common::Validation::invalid(
        fmt::format("second_order.max_end_weight must be in [0, 1], got {}", so.max_end_weight));
  if (bad(so.reference_sigma_over_r) || !(so.reference_sigma_over_r > 0.0))
    return common::Validation::invalid(
        fmt::format("second_order.reference_sigma_over_r must be > 0, got {}", so.reference_sigma_over_r));
  if (bad(so.full_weighting_arc_deg) || bad(so.no_weighting_arc_deg) || so.full_weighting_arc_deg < 0.0 ||
      so.no_weighting_arc_deg < so.full_weighting_arc_deg)
    return common::Validation::invalid(
        fmt::format("second_order needs 0 <= full_weighting_arc_deg <= no_weighting_arc_deg, got {} and {}",
                    so.full_weighting_arc_deg, so.no_weighting_arc_deg));
  if (bad(so.full_weighting_rel_sd_r) || bad(so.no_weighting_rel_sd_r) || so.full_weighting_rel_sd_r < 0.0 ||
      so.no_weighting_rel_sd_r < so.full_weighting_rel_sd_r)
    return common::Validation::invalid(
        fmt::format("second_order needs 0 <= full_weighting_rel_sd_r <= no_weighting_rel_sd_r, got {} and {}",
                    so.full_weighting_rel_sd_r, so.no_weighting_rel_sd_r));
  if (std::isnan(so.max_sigma_over_r) || !(so.max_sigma_over_r > 0.0))
    return common::Validation::invalid(
        fmt::format("second_order.max_sigma_over_r must be > 0, got {}", so.max_sigma_over_r));
  if (so.max_points < 3)
    return common::Validation::invalid(fmt::format("second_order.max_points must be >= 3, got {}", so.max_points));
  if (bad(so.mode_shift) || so.mode_shift < 0.0)
    return common::Validation::invalid(fmt::format("second_order.mode_shift must be >= 0, got {}", so.mode_shift));
  if (bad(so.max_shift_sds) || so.max_shift_sds < 0.0)
    return common::Validation::invalid(
        fmt::format("second_order.max_shift_sds must be >= 0, got {}", so.max_shift_sds));
  return common::Validation::ok();
}

/// The arc n points cover about `centre`: 2 pi minus the largest angular gap
/// between neighbouring points, and the direction of its middle, to the
/// resolution of kArcBins bins of angle (a sort would cost more than the
/// refit it serves). Fills `ang` with each point's angle [rad].
struct ArcSpan {
  double span_rad = 0.0;
  double mid_rad = 0.0;
};
constexpr int kArcBins = 720;

/// atan2 to ~1e-5 rad (a minimax polynomial of atan on [0, 1], folded by
/// octant): the arc's bins and end weights need no more, and std::atan2 on
/// every point cost as much as the rest of the correction.
double fast_atan2(double y, double x) {
  const double ax = std::abs(x), ay = std::abs(y);
  const double hi = std::max(ax, ay);
  if (hi == 0.0) return 0.0;
  const double t = std::min(ax, ay) / hi;
  const double t2 = t * t;
  double a = t * (0.9998660 + t2 * (-0.3302995 + t2 * (0.1801410 + t2 * (-0.0851330 + t2 * 0.0208351))));
  if (ay > ax) a = 0.5 * std::numbers::pi - a;
  if (x < 0.0) a = std::numbers::pi - a;
  return y < 0.0 ? -a : a;
}
ArcSpan arc_span(const double* px, const double* py, int n, const Eigen::Vector2d& centre, std::vector<double>& ang) {
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  constexpr double kBin = kTwoPi / kArcBins;
  const auto un = static_cast<std::size_t>(n);
  ang.resize(un);
  std::array<bool, kArcBins> occupied{};
  for (std::size_t k = 0; k < un; ++k) {
    ang[k] = fast_atan2(py[k] - centre.y(), px[k] - centre.x());
    const int b = std::clamp(static_cast<int>((ang[k] + std::numbers::pi) / kBin), 0, kArcBins - 1);
    occupied[static_cast<std::size_t>(b)] = true;
  }
  // The longest run of empty bins, around the circle (two passes).
  int best = 0, best_end = 0, run = 0;
  for (int i = 0; i < 2 * kArcBins; ++i) {
    if (occupied[static_cast<std::size_t>(i % kArcBins)]) {
      run = 0;
    } else if (++run > best) {
      best = std::min(run, kArcBins);
      best_end = i;
    }
  }
  // The gap spans the empty run and, on average, half of each occupied bin at its ends.
  const double gap = (best + 1) * kBin;
  const double gap_mid = -std::numbers::pi + (best_end + 1 - 0.5 * best) * kBin;
  return ArcSpan{std::max(0.0, kTwoPi - gap), gap_mid + std::numbers::pi};
}

}  // namespace

CircleFit fit_circle_kasa(const Eigen::Ref<const Eigen::Matrix2Xd>& points) {
  const Normalised n = normalise(points);
  if (auto bad = check_algebraic_input(n, "Kasa")) return *bad;
  // min sum (z + D x + E y + F)^2: normal equations of [x y 1] against -z.
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (Eigen::Index i = 0; i < n.q.cols(); ++i) {
    const Eigen::Vector3d u(n.q(0, i), n.q(1, i), 1.0);
    M.noalias() += u * u.transpose();
    rhs -= u * n.q.col(i).squaredNorm();
  }
  const Eigen::Vector3d x = M.ldlt().solve(rhs);
  return from_algebraic(Eigen::Vector4d(1.0, x(0), x(1), x(2)), n, points, "Kasa");
}

namespace {

/// The Hyper fit's algebraic parameters for checked, normalised points.
Eigen::Vector4d hyper_parameters(const Normalised& n) {
  // Moments of Z = [z x y 1] (data centred, so mean x = mean y = 0): the ten
  // distinct sums of the symmetric u u^T, each added in point order.
  double zz = 0, zx = 0, zy = 0, xx = 0, xy = 0, yy = 0, sx = 0, sy = 0;
  double zbar = 0.0;
  for (Eigen::Index i = 0; i < n.q.cols(); ++i) {
    const double x = n.q(0, i), y = n.q(1, i);
    const double z = n.q.col(i).squaredNorm();
    zz += z * z;
    zx += z * x;
    zy += z * y;
    xx += x * x;
    xy += x * y;
    yy += y * y;
    sx += x;
    sy += y;
    zbar += z;
  }
  Eigen::Matrix4d M;
  M << zz, zx, zy, zbar, zx, xx, xy, sx, zy, xy, yy, sy, zbar, sx, sy, static_cast<double>(n.q.cols());
  const double k = static_cast<double>(n.q.cols());
  M /= k;
  zbar /= k;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es(M);
  const Eigen::Vector4d lam = es.eigenvalues().cwiseMax(0.0);
  Eigen::Vector4d A;
  if (lam(0) <= 1e-14 * lam(3)) {
    // Points on a circle to rounding precision: the null vector is the fit.
    A = es.eigenvectors().col(0);
  } else {
    // Hyper constraint matrix (Al-Sharadqah & Chernov 2009) for centred data.
    Eigen::Matrix4d N = Eigen::Matrix4d::Zero();
    N(0, 0) = 8.0 * zbar;
    N(0, 3) = N(3, 0) = 2.0;
    N(1, 1) = N(2, 2) = 1.0;
    // M A = eta N A  <=>  W N^-1 W C = eta C with W = M^(1/2), C = W A; the
    // smallest positive eta (N has one negative eigenvalue) is the second.
    const Eigen::Matrix4d& V = es.eigenvectors();
    const Eigen::Matrix4d W = V * lam.cwiseSqrt().asDiagonal() * V.transpose();
    const Eigen::Matrix4d Winv = V * lam.cwiseSqrt().cwiseInverse().asDiagonal() * V.transpose();
    Eigen::Matrix4d Ninv = Eigen::Matrix4d::Zero();
    Ninv(0, 3) = Ninv(3, 0) = 0.5;
    Ninv(1, 1) = Ninv(2, 2) = 1.0;
    Ninv(3, 3) = -2.0 * zbar;  // inverse of [[8z, 2], [2, 0]] is [[0, 1/2], [1/2, -2z]]
    const Eigen::Matrix4d S = W * Ninv * W;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> gs(0.5 * (S + S.transpose()));
    A = Winv * gs.eigenvectors().col(1);
  }
  return A;
}

}  // namespace

CircleFit fit_circle_hyper(const Eigen::Ref<const Eigen::Matrix2Xd>& points) {
  const Normalised n = normalise(points);
  if (auto bad = check_algebraic_input(n, "Hyper")) return *bad;
  return from_algebraic(hyper_parameters(n), n, points, "Hyper");
}

CircleFit fit_circle_taubin(const Eigen::Ref<const Eigen::Matrix2Xd>& points) {
  const Normalised n = normalise(points);
  if (auto bad = check_algebraic_input(n, "Taubin")) return *bad;
  const double k = static_cast<double>(n.q.cols());
  double zmean = n.q.squaredNorm() / k;  // 1 after normalisation, kept general
  const double s = 2.0 * std::sqrt(zmean);
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  for (Eigen::Index i = 0; i < n.q.cols(); ++i) {
    const Eigen::Vector3d u((n.q.col(i).squaredNorm() - zmean) / s, n.q(0, i), n.q(1, i));
    M.noalias() += u * u.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(M);
  const Eigen::Vector3d a = es.eigenvectors().col(0);
  const double a0 = a(0) / s;
  return from_algebraic(Eigen::Vector4d(a0, a(1), a(2), -zmean * a0), n, points, "Taubin");
}

common::Validation validate(const RefineParams& params) {
  if (params.known_radius_m && !(*params.known_radius_m > 0.0 && std::isfinite(*params.known_radius_m)))
    return common::Validation::invalid(
        fmt::format("known_radius_m must be finite and > 0, got {}", *params.known_radius_m));
  if (params.max_iterations < 1)
    return common::Validation::invalid(fmt::format("max_iterations must be >= 1, got {}", params.max_iterations));
  if (params.correction == ArcCorrection::kSecondOrder) return validate_second_order(params.second_order);
  return common::Validation::ok();
}

common::Validation validate(const RobustCircleParams& params) {
  const bool known = params.known_radius_m.has_value();
  if (!(params.inlier_threshold_m > 0.0) || !std::isfinite(params.inlier_threshold_m))
    return common::Validation::invalid(
        fmt::format("inlier_threshold_m must be > 0, got {}", params.inlier_threshold_m));
  if (!(params.min_radius_m >= 0.0) || !(params.max_radius_m > params.min_radius_m))
    return common::Validation::invalid(
        fmt::format("need 0 <= min_radius_m < max_radius_m, got [{}, {}]", params.min_radius_m, params.max_radius_m));
  if (known && !(*params.known_radius_m > 0.0 && std::isfinite(*params.known_radius_m)))
    return common::Validation::invalid(
        fmt::format("known_radius_m must be finite and > 0, got {}", *params.known_radius_m));
  if (params.max_iterations < 1)
    return common::Validation::invalid(fmt::format("max_iterations must be >= 1, got {}", params.max_iterations));
  if (!(params.confidence > 0.0 && params.confidence < 1.0))
    return common::Validation::invalid(fmt::format("confidence must be in (0, 1), got {}", params.confidence));
  if (params.min_inliers < (known ? 2 : 3))
    return common::Validation::invalid(
        fmt::format("min_inliers must be >= {}, got {}", known ? 2 : 3, params.min_inliers));
  if (!(params.inlier_threshold_sigmas >= 0.0))
    return common::Validation::invalid(
        fmt::format("inlier_threshold_sigmas must be >= 0, got {}", params.inlier_threshold_sigmas));
  return common::Validation::ok();
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

bool second_order_applies(const SecondOrderCorrection& so, int n, double q) {
  return n <= so.max_points && q <= so.max_sigma_over_r;
}

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
  f.status = FitStatus::kOk;
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
  const double qr = q / so.reference_sigma_over_r;
  const double var_r0 = f.covariance(2, 2);
  const double rel_sd_r = var_r0 > 0.0 ? std::sqrt(var_r0) / f.circle.radius_m : 0.0;
  const double k_noise = std::min(so.max_end_weight, so.end_weight * qr * qr) *
                         fade(rel_sd_r, so.full_weighting_rel_sd_r, so.no_weighting_rel_sd_r);
  if (!(k_noise > kMinEndWeight)) return;
  std::vector<double> ang;  // each point's angle about the centre [rad]
  const ArcSpan arc = arc_span(pts.px, pts.py, pts.n, f.circle.centre_m, ang);
  const double span_deg = arc.span_rad * 180.0 / std::numbers::pi;
  const double k_end = k_noise * fade(span_deg, so.full_weighting_arc_deg, so.no_weighting_arc_deg);
  if (!(k_end > kMinEndWeight && arc.span_rad > 0.0)) return;
  for (int k = 0; k < pts.n; ++k) {
    const double u =
        std::remainder(ang[static_cast<std::size_t>(k)] - arc.mid_rad, 2.0 * std::numbers::pi) / (0.5 * arc.span_rad);
    pts.pw[k] *= std::max(kMinRelativeWeight, 1.0 - k_end * u * u);
  }
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

/// Step 2: theta -= gamma Cov(theta, r) / r, the shift of r capped.
void shift_to_the_mode(CircleFit& f, const SecondOrderCorrection& so) {
  const double var_r = f.covariance(2, 2);
  if (!(so.mode_shift > 0.0 && var_r > 0.0 && std::isfinite(var_r))) return;
  const double r = f.circle.radius_m;
  const double rel = std::sqrt(var_r) / r;
  const double gamma = std::min(so.mode_shift, so.max_shift_sds / rel);
  const Eigen::Vector3d shift = -gamma * f.covariance.col(2) / r;
  if (shift.allFinite()) {
    f.circle.centre_m += shift.head<2>();
    f.circle.radius_m += shift(2);
    f.mode_shift_m = shift;
  }
}

}  // namespace

CircleFit refine_circle(const Eigen::Ref<const Eigen::Matrix2Xd>& points, const Circle& initial,
                        const RefineParams& params, std::span<const double> sigma_m) {
  const bool known = params.known_radius_m.has_value();
  if (const common::Validation v = validate(params); !v.valid) return failed(FitStatus::kInvalidParams, v.reason);
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
    if (params.known_radius_m && init.status == FitStatus::kCollinear) {
      // A known radius still fixes a circle through collinear points (two
      // mirror solutions); the algebraic start cannot, so say so plainly.
      init.reason += " (a known radius does not resolve which side the centre is on)";
    }
    return init;
  }
  CircleFit f = refine_circle(points, init.circle, params, sigma_m);
  return f;
}

// ---------------------------------------------------------------------------- robust

std::optional<Circle> circle_through(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const Eigen::Vector2d ab = b - a, ac = c - a;
  const double d = 2.0 * (ab.x() * ac.y() - ab.y() * ac.x());
  // d / 2 = |ab| |ac| sin(angle at a): below a sine of 1e-9 the points are
  // collinear to rounding (or two coincide) and the centre is meaningless.
  if (!(std::abs(d) > 2e-9 * ab.norm() * ac.norm())) return std::nullopt;
  const double ab2 = ab.squaredNorm(), ac2 = ac.squaredNorm();
  const Eigen::Vector2d o((ac.y() * ab2 - ab.y() * ac2) / d, (ab.x() * ac2 - ac.x() * ab2) / d);
  Circle circle{a + o, o.norm()};
  if (!std::isfinite(circle.radius_m)) return std::nullopt;
  return circle;
}

namespace {

struct Consensus {
  double score = std::numeric_limits<double>::infinity();
  int inliers = 0;
};

/// The input check fit_circle_robust makes first: the parameters, the
/// per-point sigmas and the viewpoints' indices.
std::optional<CircleFit> check_robust_input(const Eigen::Ref<const Eigen::Matrix2Xd>& points,
                                            const RobustCircleParams& params, std::span<const double> sigma_m,
                                            const Viewpoints& viewpoints) {
  auto invalid = [](std::string r) { return failed(FitStatus::kInvalidParams, std::move(r)); };
  if (const common::Validation v = validate(params); !v.valid) return invalid(v.reason);
  if (!sigma_m.empty() && sigma_m.size() != static_cast<std::size_t>(points.cols()))
    return invalid(fmt::format("sigma_m has {} entries for {} points", sigma_m.size(), points.cols()));
  for (std::size_t i = 0; i < sigma_m.size(); ++i)
    if (!(sigma_m[i] > 0.0) || !std::isfinite(sigma_m[i]))
      return invalid(fmt::format("sigma_m[{}] = {} is not a finite positive SD", i, sigma_m[i]));
  if (viewpoints.origins_m.empty()) return std::nullopt;
  if (viewpoints.sensor_of_point.size() != static_cast<std::size_t>(points.cols()))
    return invalid(fmt::format("viewpoints.sensor_of_point has {} entries for {} points",
                               viewpoints.sensor_of_point.size(), points.cols()));
  for (const int s : viewpoints.sensor_of_point)
    if (s < 0 || static_cast<std::size_t>(s) >= viewpoints.origins_m.size())
      return invalid(
          fmt::format("viewpoints.sensor_of_point holds {} but there are {} origins", s, viewpoints.origins_m.size()));
  return std::nullopt;
}

/// fit_circle_robust's steps on one input: the finite points laid out,
/// MSAC over minimal samples, local optimisation of the consensus set, the
/// final fit.
class RobustCircleFitter {
 public:
  RobustCircleFitter(const Eigen::Ref<const Eigen::Matrix2Xd>& points, const RobustCircleParams& params,
                     std::span<const double> sigma_m, const Viewpoints& viewpoints)
      : points_(points),
        params_(params),
        sigma_m_(sigma_m),
        viewpoints_(viewpoints),
        known_(params.known_radius_m.has_value()),
        s_(known_ ? 2 : 3) {}

  CircleFit run() {
    if (auto f = lay_out()) return *f;
    if (auto f = sample()) return *f;
    local_optimisation();
    return final_fit();
  }

 private:
  const Eigen::Ref<const Eigen::Matrix2Xd>& points_;
  const RobustCircleParams& params_;
  std::span<const double> sigma_m_;
  const Viewpoints& viewpoints_;
  const bool known_;
  const int s_;           ///< minimal sample
  std::vector<int> idx_;  ///< finite points
  int n_ = 0, non_finite_ = 0;
  double T2_ = 0.0, trunc_ = 0.0;
  const Eigen::Vector2d* vp_ = nullptr;
  // Every pass reads the finite points in order, so what it needs of each is
  // laid out contiguously once: coordinates, the squared support limit
  // min(T^2, k^2 sigma^2), the score unit (sigma^2, or 1), sigma (1 without
  // sigmas), its sensor's origin, and the residual of the last pass.
  std::vector<double> buf_;
  double *x_ = nullptr, *y_ = nullptr, *lim2_ = nullptr, *unit2_ = nullptr, *sg_ = nullptr, *ox_ = nullptr,
         *oy_ = nullptr, *res_ = nullptr;
  // MSAC
  Circle best_{};
  Consensus best_c_;
  int drawn_ = 0, valid_ = 0, out_of_range_ = 0;
  long long needed_ = 0;
  // Local optimisation: per finite point, the set, the set before a round,
  // and the support of the last residual pass.
  std::vector<std::uint8_t> mask_, before_, support_;
  int count_ = 0;
  Circle current_{};
  RefineParams rp_;
  Eigen::Matrix2Xd inl_;
  std::vector<double> inl_sigma_, e_;
  Normalised set_;

  std::optional<CircleFit> lay_out();
  std::optional<CircleFit> sample();
  void consider(const Circle& c);
  void local_optimisation();
  CircleFit final_fit();

  /// Point k supports circle c when it is within its limit of it and, with
  /// viewpoints, faces its sensor (outward normal towards the viewpoint).
  /// *d is its signed distance to the circle.
  bool supports(int k, const Circle& c, double* d) const {
    const double dx = x_[k] - c.centre_m.x(), dy = y_[k] - c.centre_m.y();
    *d = std::sqrt(dx * dx + dy * dy) - c.radius_m;
    if (*d * *d > lim2_[k]) return false;
    if (vp_ && dx * (ox_[k] - x_[k]) + dy * (oy_[k] - y_[k]) <= 0.0) return false;
    return true;
  }
  bool viewpoints_outside(const Circle& c) const {
    if (!vp_) return true;
    for (const auto& o : viewpoints_.origins_m)
      if ((o - c.centre_m).norm() < c.radius_m) return false;
    return true;
  }
  /// MSAC cost with early exit once above `bound`.
  Consensus score(const Circle& c, double bound) const {
    Consensus r;
    double sc = 0.0;
    for (int k = 0; k < n_; ++k) {
      double d;
      if (supports(k, c, &d)) {
        sc += d * d / unit2_[k];
        ++r.inliers;
      } else {
        sc += trunc_;
      }
      if (sc > bound) return Consensus{};
    }
    r.score = sc;
    return r;
  }
  void residuals(const Circle& c) {
    for (int k = 0; k < n_; ++k) support_[static_cast<std::size_t>(k)] = supports(k, c, &res_[k]) ? 1 : 0;
  }
  /// The set of the last residual pass's circle: its supporters, within
  /// scaled_limit of their own sigma when > 0.
  int select(double scaled_limit) {
    int count = 0;
    for (int k = 0; k < n_; ++k) {
      const auto uk = static_cast<std::size_t>(k);
      mask_[uk] = support_[uk] && !(scaled_limit > 0.0 && std::abs(res_[k]) > scaled_limit * sg_[k]) ? 1 : 0;
      count += mask_[uk];
    }
    return count;
  }
  /// Robust scale of the current set's normalised residuals to the last
  /// residual pass's circle, times the factor.
  double adaptive_limit() {
    if (!(params_.final_threshold_sigmas > 0.0)) return 0.0;
    e_.clear();
    for (int k = 0; k < n_; ++k)
      if (mask_[static_cast<std::size_t>(k)]) e_.push_back(std::abs(res_[k]) / sg_[k]);
    if (e_.size() < static_cast<std::size_t>(2 * s_)) return 0.0;
    std::nth_element(e_.begin(), e_.begin() + static_cast<long>(e_.size() / 2), e_.end());
    return params_.final_threshold_sigmas * 1.4826 * e_[e_.size() / 2];
  }
  /// The set's points (and sigmas) into inl_ for a geometric fit.
  void gather(int count) {
    inl_.resize(2, count);
    inl_sigma_.clear();
    Eigen::Index j = 0;
    for (int k = 0; k < n_; ++k) {
      if (!mask_[static_cast<std::size_t>(k)]) continue;
      inl_(0, j) = x_[k];
      inl_(1, j++) = y_[k];
      if (!sigma_m_.empty()) inl_sigma_.push_back(sg_[k]);
    }
  }
  /// The Hyper fit of the set (what fit_circle_hyper gives for the gathered
  /// set), normalised straight from the contiguous points.
  std::optional<Circle> hyper_of_set(int count) {
    set_.q.resize(2, count);
    Eigen::Index j = 0;
    for (int k = 0; k < n_; ++k) {
      if (!mask_[static_cast<std::size_t>(k)]) continue;
      set_.q(0, j) = x_[k];
      set_.q(1, j++) = y_[k];
    }
    centre_and_scale(set_);
    if (count < 3 || planarity(set_.q) < kCollinearPlanarity) return std::nullopt;
    return circle_from_algebraic(hyper_parameters(set_), set_);
  }
};

std::optional<CircleFit> RobustCircleFitter::lay_out() {
  idx_.reserve(static_cast<std::size_t>(points_.cols()));
  for (Eigen::Index i = 0; i < points_.cols(); ++i) {
    if (finite(points_.col(i))) {
      idx_.push_back(static_cast<int>(i));
    } else {
      ++non_finite_;
    }
  }
  n_ = static_cast<int>(idx_.size());
  if (n_ < std::max(s_, params_.min_inliers)) {
    return failed(
        FitStatus::kTooFewPoints,
        fmt::format("robust circle fit needs at least {} finite points, got {}{}", std::max(s_, params_.min_inliers),
                    n_, non_finite_ ? fmt::format(" ({} non-finite skipped)", non_finite_) : ""),
        non_finite_);
  }
  const double T = params_.inlier_threshold_m;
  T2_ = T * T;
  vp_ = viewpoints_.origins_m.empty() ? nullptr : viewpoints_.origins_m.data();
  // With per-point sigmas, support and score are in units of each point's
  // sigma (a near point with 4 mm noise must not accept 2 cm residuals a far
  // one would); the absolute threshold still caps.
  const bool per_point = !sigma_m_.empty() && params_.inlier_threshold_sigmas > 0.0;
  const double k2 = params_.inlier_threshold_sigmas * params_.inlier_threshold_sigmas;
  trunc_ = per_point ? k2 : T2_;  // MSAC truncation, in score units
  const int n = n_;
  buf_.resize(8 * static_cast<std::size_t>(n));
  x_ = buf_.data();
  y_ = x_ + n;
  lim2_ = y_ + n;
  unit2_ = lim2_ + n;
  sg_ = unit2_ + n;
  ox_ = sg_ + n;
  oy_ = ox_ + n;
  res_ = oy_ + n;
  for (int k = 0; k < n; ++k) {
    const auto i = static_cast<std::size_t>(idx_[static_cast<std::size_t>(k)]);
    x_[k] = points_(0, idx_[static_cast<std::size_t>(k)]);
    y_[k] = points_(1, idx_[static_cast<std::size_t>(k)]);
    sg_[k] = sigma_m_.empty() ? 1.0 : sigma_m_[i];
    unit2_[k] = per_point ? sg_[k] * sg_[k] : 1.0;
    lim2_[k] = per_point ? std::min(T2_, k2 * unit2_[k]) : T2_;
    ox_[k] = vp_ ? vp_[viewpoints_.sensor_of_point[i]].x() : 0.0;
    oy_[k] = vp_ ? vp_[viewpoints_.sensor_of_point[i]].y() : 0.0;
  }
  if (!known_) {
    Eigen::Matrix2Xd q(2, n);
    q.row(0) = Eigen::Map<const Eigen::RowVectorXd>(x_, n);
    q.row(1) = Eigen::Map<const Eigen::RowVectorXd>(y_, n);
    q.colwise() -= q.rowwise().mean();
    if (planarity(q) < kCollinearPlanarity) {
      return failed(FitStatus::kCollinear, fmt::format("the {} points are collinear", n), non_finite_);
    }
  }
  return std::nullopt;
}

void RobustCircleFitter::consider(const Circle& c) {
  if (c.radius_m < params_.min_radius_m || c.radius_m > params_.max_radius_m) {
    ++out_of_range_;
    return;
  }
  if (!viewpoints_outside(c)) return;
  ++valid_;
  const Consensus r = score(c, best_c_.score);
  if (r.score < best_c_.score) {
    best_c_ = r;
    best_ = c;
    const double eps = static_cast<double>(r.inliers) / n_;
    const double pin = std::pow(eps, s_);
    if (pin >= 1.0) {
      needed_ = 0;
    } else if (pin > 0.0) {
      needed_ =
          std::min<long long>(params_.max_iterations,
                              static_cast<long long>(std::ceil(std::log(1.0 - params_.confidence) / std::log1p(-pin))));
    }
  }
}

std::optional<CircleFit> RobustCircleFitter::sample() {
  common::SplitMixRandom rng(params_.seed);
  needed_ = params_.max_iterations;
  const auto un64 = static_cast<std::uint64_t>(n_);
  while (drawn_ < needed_ && drawn_ < params_.max_iterations) {
    ++drawn_;
    const auto a = static_cast<int>(rng.below(un64));
    const auto b = static_cast<int>(rng.below(un64));
    if (b == a) continue;
    const Eigen::Vector2d pa(x_[a], y_[a]), pb(x_[b], y_[b]);
    if (known_) {
      // Two centres at distance R from both points (mirror images).
      const double R = *params_.known_radius_m;
      const double half = 0.5 * (pb - pa).norm();
      if (half > R || half == 0.0) continue;
      const Eigen::Vector2d mid = 0.5 * (pa + pb);
      const Eigen::Vector2d perp = Eigen::Vector2d(-(pb - pa).y(), (pb - pa).x()) / (2.0 * half);
      const double h = std::sqrt(R * R - half * half);
      consider(Circle{mid + h * perp, R});
      consider(Circle{mid - h * perp, R});
    } else {
      const auto c = static_cast<int>(rng.below(un64));
      if (c == a || c == b) continue;
      const auto circ = circle_through(pa, pb, Eigen::Vector2d(x_[c], y_[c]));
      if (!circ) continue;
      consider(*circ);
    }
  }
  if (best_c_.inliers > 0) return std::nullopt;
  if (valid_ == 0 && out_of_range_ > 0) {
    return failed(FitStatus::kRadiusOutOfRange,
                  fmt::format("all {} circles through samples of the {} points had radii outside [{}, {}] m "
                              "(a straight or too curved surface)",
                              out_of_range_, n_, params_.min_radius_m, params_.max_radius_m),
                  non_finite_);
  }
  return failed(FitStatus::kNoConsensus,
                fmt::format("no circle hypothesis from {} samples of {} points was supported", drawn_, n_),
                non_finite_);
}

// Fit the consensus set, re-select, repeat. The first selection uses
// inlier_threshold_m; later ones also the set's own residual scale
// (final_threshold_sigmas), so clutter just inside a generous threshold
// (worst: a point on the unobserved side of a short arc, which has high
// leverage) cannot hold the fit. Each candidate circle costs one pass over
// the points (residuals and support), which both the scale and the
// selection read.
void RobustCircleFitter::local_optimisation() {
  const auto un = static_cast<std::size_t>(n_);
  mask_.assign(un, 0);
  before_.assign(un, 0);
  support_.assign(un, 0);
  e_.reserve(un);
  rp_ = params_.refine;
  rp_.known_radius_m = params_.known_radius_m;
  current_ = best_;
  residuals(current_);
  count_ = select(0.0);
  bool moved = false;
  const int rounds = std::max(1, params_.local_optimisation_rounds) + (params_.final_threshold_sigmas > 0.0 ? 3 : 0);
  for (int round = 0; round < rounds; ++round) {
    // Re-selection rounds use the algebraic fit: cheap, and within a small
    // fraction of the ML fit at these noise levels. A known radius needs LM.
    std::optional<Circle> next;
    if (known_) {
      gather(count_);
      const CircleFit f = refine_circle(inl_, current_, rp_, inl_sigma_);
      if (f.ok()) next = f.circle;
    } else {
      next = hyper_of_set(count_);
    }
    if (!next) break;  // e.g. a collinear consensus set: keep the hypothesis
    before_ = mask_;
    const int before_count = count_;
    residuals(*next);
    const double limit = adaptive_limit();
    const int k = select(limit);
    if (limit == 0.0 && k < before_count && moved) {
      mask_ = before_;  // the refit lost support: keep the previous set
      count_ = before_count;
      break;
    }
    current_ = *next;
    moved = true;
    count_ = k;
    if (mask_ == before_) break;
  }
}

// The final fit on the final set: geometric (ML) unless the caller refits.
CircleFit RobustCircleFitter::final_fit() {
  CircleFit fit;
  if (params_.final_geometric_fit || known_) {
    gather(count_);
    fit = refine_circle(inl_, current_, rp_, inl_sigma_);
  }
  if (!fit.ok()) {
    fit = CircleFit{};
    fit.status = FitStatus::kOk;
    fit.circle = current_;
    double ss = 0.0;
    for (int k = 0; k < n_; ++k) {
      if (!mask_[static_cast<std::size_t>(k)]) continue;
      const double dx = x_[k] - current_.centre_m.x(), dy = y_[k] - current_.centre_m.y();
      const double d = std::sqrt(dx * dx + dy * dy) - current_.radius_m;
      ss += d * d;
    }
    fit.rms_residual_m = count_ ? std::sqrt(ss / count_) : 0.0;
  }
  fit.iterations = drawn_;
  fit.non_finite = non_finite_;
  fit.inlier_mask.assign(static_cast<std::size_t>(points_.cols()), 0);
  for (int k = 0; k < n_; ++k)
    fit.inlier_mask[static_cast<std::size_t>(idx_[static_cast<std::size_t>(k)])] = mask_[static_cast<std::size_t>(k)];
  fit.points_used = count_;
  if (count_ < params_.min_inliers) {
    fit.status = FitStatus::kNoConsensus;
    fit.reason = fmt::format("best circle has {} inliers of {} points, fewer than min_inliers = {}", count_, n_,
                             params_.min_inliers);
    return fit;
  }
  if (fit.circle.radius_m < params_.min_radius_m || fit.circle.radius_m > params_.max_radius_m) {
    fit.status = FitStatus::kRadiusOutOfRange;
    fit.reason = fmt::format("fitted radius {:.4f} m is outside [{}, {}] m", fit.circle.radius_m, params_.min_radius_m,
                             params_.max_radius_m);
    return fit;
  }
  return fit;
}

}  // namespace

CircleFit fit_circle_robust(const Eigen::Ref<const Eigen::Matrix2Xd>& points, const RobustCircleParams& params,
                            std::span<const double> sigma_m, const Viewpoints& viewpoints) {
  if (auto f = check_robust_input(points, params, sigma_m, viewpoints)) return *f;
  return RobustCircleFitter(points, params, sigma_m, viewpoints).run();
}

// ---------------------------------------------------------------------------- KCR

KcrBound kcr_bound(const Eigen::Ref<const Eigen::Matrix2Xd>& true_points, const Circle& truth,
                   std::span<const double> sigma_m, bool known_radius) {
  KcrBound b;
  const auto n = true_points.cols();
  if (sigma_m.size() != 1 && sigma_m.size() != static_cast<std::size_t>(n)) {
    b.reason = fmt::format("sigma_m needs 1 or {} entries, got {}", n, sigma_m.size());
    return b;
  }
  Eigen::Matrix3d W = Eigen::Matrix3d::Zero();
  for (Eigen::Index i = 0; i < n; ++i) {
    const double s = sigma_m.size() == 1 ? sigma_m[0] : sigma_m[static_cast<std::size_t>(i)];
    if (!(s > 0.0) || !std::isfinite(s) || !finite(true_points.col(i))) {
      b.reason = fmt::format("point {} has a non-finite coordinate or sigma {}", i, s);
      return b;
    }
    const Eigen::Vector2d dv = true_points.col(i) - truth.centre_m;
    const double rho = dv.norm();
    if (rho == 0.0) {
      b.reason = fmt::format("point {} is at the centre", i);
      return b;
    }
    const Eigen::Vector3d g(-dv.x() / rho, -dv.y() / rho, -1.0);
    W.noalias() += g * g.transpose() / (s * s);
  }
  if (known_radius) {
    Eigen::FullPivLU<Eigen::Matrix2d> lu(W.topLeftCorner<2, 2>());
    if (!lu.isInvertible()) {
      b.reason = "information matrix is singular (fewer than 2 distinct directions)";
      return b;
    }
    b.covariance.topLeftCorner<2, 2>() = lu.inverse();
  } else {
    Eigen::FullPivLU<Eigen::Matrix3d> lu(W);
    if (!lu.isInvertible() || n < 3) {
      b.reason = "information matrix is singular (fewer than 3 distinct directions)";
      return b;
    }
    b.covariance = lu.inverse();
  }
  b.ok = true;
  return b;
}

}  // namespace tinyline::hydrus_fitting
