// SPDX-License-Identifier: Apache-2.0
// The robust circle fit: MSAC over minimal samples, local optimisation of
// the consensus set, the final geometric fit.
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

common::Status validate(const RobustCircleParams& params) {
  const bool known = params.known_radius_m.has_value();
  if (!(params.inlier_threshold_m > 0.0) || !std::isfinite(params.inlier_threshold_m))
    return common::Status::invalid(fmt::format("inlier_threshold_m must be > 0, got {}", params.inlier_threshold_m));
  if (!(params.min_radius_m >= 0.0) || !(params.max_radius_m > params.min_radius_m))
    return common::Status::invalid(
        fmt::format("need 0 <= min_radius_m < max_radius_m, got [{}, {}]", params.min_radius_m, params.max_radius_m));
  if (known && !(*params.known_radius_m > 0.0 && std::isfinite(*params.known_radius_m)))
    return common::Status::invalid(
        fmt::format("known_radius_m must be finite and > 0, got {}", *params.known_radius_m));
  if (params.max_iterations < 1)
    return common::Status::invalid(fmt::format("max_iterations must be >= 1, got {}", params.max_iterations));
  if (!(params.confidence > 0.0 && params.confidence < 1.0))
    return common::Status::invalid(fmt::format("confidence must be in (0, 1), got {}", params.confidence));
  if (params.min_inliers < (known ? 2 : 3))
    return common::Status::invalid(fmt::format("min_inliers must be >= {}, got {}", known ? 2 : 3, params.min_inliers));
  if (!(params.inlier_threshold_sigmas >= 0.0))
    return common::Status::invalid(
        fmt::format("inlier_threshold_sigmas must be >= 0, got {}", params.inlier_threshold_sigmas));
  return common::Status{};
}

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
  if (const common::Status v = validate(params); !v.ok()) return invalid(v.message);
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
    fit.set_outcome(FitStatus::kOk);
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
    fit.set_outcome(FitStatus::kNoConsensus,
                    fmt::format("best circle has {} inliers of {} points, fewer than min_inliers = {}", count_, n_,
                                params_.min_inliers));
    return fit;
  }
  if (fit.circle.radius_m < params_.min_radius_m || fit.circle.radius_m > params_.max_radius_m) {
    fit.set_outcome(FitStatus::kRadiusOutOfRange,
                    fmt::format("fitted radius {:.4f} m is outside [{}, {}] m", fit.circle.radius_m,
                                params_.min_radius_m, params_.max_radius_m));
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

}  // namespace tinyline::hydrus_fitting
