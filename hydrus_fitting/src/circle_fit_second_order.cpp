// SPDX-License-Identifier: Apache-2.0
// The second-order correction of the geometric circle fit (docs/hydrus_fitting.md,
// "Beyond first order"): the arc's ends weighted by the noise it sees, and
// the shift to the mode.
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

namespace {

// Second-order correction: end weights below this are not worth a refit;
// no point's weight drops below this fraction.
constexpr double kMinEndWeight = 1e-3;
constexpr double kMinRelativeWeight = 0.05;

/// 1 up to `full`, 0 from `none`, linear between (a step when they are equal).
double fade(double x, double full, double none) {
  if (none > full) return std::clamp((none - x) / (none - full), 0.0, 1.0);
  return x < full ? 1.0 : 0.0;
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

bool second_order_applies(const SecondOrderCorrection& so, int n, double q) {
  return n <= so.max_points && q <= so.max_sigma_over_r;
}

namespace detail {

common::Status validate_second_order(const SecondOrderCorrection& so) {
  const auto bad = [](double v) { return !std::isfinite(v); };
  if (bad(so.end_weight) || so.end_weight < 0.0)
    return common::Status::invalid(fmt::format("second_order.end_weight must be >= 0, got {}", so.end_weight));
  if (bad(so.max_end_weight) || so.max_end_weight < 0.0 || so.max_end_weight > 1.0)
    return common::Status::invalid(
        fmt::format("second_order.max_end_weight must be in [0, 1], got {}", so.max_end_weight));
  if (bad(so.reference_sigma_over_r) || !(so.reference_sigma_over_r > 0.0))
    return common::Status::invalid(
        fmt::format("second_order.reference_sigma_over_r must be > 0, got {}", so.reference_sigma_over_r));
  if (bad(so.full_weighting_arc_deg) || bad(so.no_weighting_arc_deg) || so.full_weighting_arc_deg < 0.0 ||
      so.no_weighting_arc_deg < so.full_weighting_arc_deg)
    return common::Status::invalid(
        fmt::format("second_order needs 0 <= full_weighting_arc_deg <= no_weighting_arc_deg, got {} and {}",
                    so.full_weighting_arc_deg, so.no_weighting_arc_deg));
  if (bad(so.full_weighting_rel_sd_r) || bad(so.no_weighting_rel_sd_r) || so.full_weighting_rel_sd_r < 0.0 ||
      so.no_weighting_rel_sd_r < so.full_weighting_rel_sd_r)
    return common::Status::invalid(
        fmt::format("second_order needs 0 <= full_weighting_rel_sd_r <= no_weighting_rel_sd_r, got {} and {}",
                    so.full_weighting_rel_sd_r, so.no_weighting_rel_sd_r));
  if (std::isnan(so.max_sigma_over_r) || !(so.max_sigma_over_r > 0.0))
    return common::Status::invalid(
        fmt::format("second_order.max_sigma_over_r must be > 0, got {}", so.max_sigma_over_r));
  if (so.max_points < 3)
    return common::Status::invalid(fmt::format("second_order.max_points must be >= 3, got {}", so.max_points));
  if (bad(so.mode_shift) || so.mode_shift < 0.0)
    return common::Status::invalid(fmt::format("second_order.mode_shift must be >= 0, got {}", so.mode_shift));
  if (bad(so.max_shift_sds) || so.max_shift_sds < 0.0)
    return common::Status::invalid(fmt::format("second_order.max_shift_sds must be >= 0, got {}", so.max_shift_sds));
  return common::Status{};
}

double weight_the_arc_ends(const CircleFit& f, const double* px, const double* py, double* pw, int n, double q,
                           const SecondOrderCorrection& so) {
  const double qr = q / so.reference_sigma_over_r;
  const double var_r0 = f.covariance(2, 2);
  const double rel_sd_r = var_r0 > 0.0 ? std::sqrt(var_r0) / f.circle.radius_m : 0.0;
  const double k_noise = std::min(so.max_end_weight, so.end_weight * qr * qr) *
                         fade(rel_sd_r, so.full_weighting_rel_sd_r, so.no_weighting_rel_sd_r);
  if (!(k_noise > kMinEndWeight)) return 0.0;
  std::vector<double> ang;  // each point's angle about the centre [rad]
  const ArcSpan arc = arc_span(px, py, n, f.circle.centre_m, ang);
  const double span_deg = arc.span_rad * 180.0 / std::numbers::pi;
  const double k_end = k_noise * fade(span_deg, so.full_weighting_arc_deg, so.no_weighting_arc_deg);
  if (!(k_end > kMinEndWeight && arc.span_rad > 0.0)) return 0.0;
  for (int k = 0; k < n; ++k) {
    const double u =
        std::remainder(ang[static_cast<std::size_t>(k)] - arc.mid_rad, 2.0 * std::numbers::pi) / (0.5 * arc.span_rad);
    pw[k] *= std::max(kMinRelativeWeight, 1.0 - k_end * u * u);
  }
  return k_end;
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

}  // namespace detail

}  // namespace tinyline::hydrus_fitting
