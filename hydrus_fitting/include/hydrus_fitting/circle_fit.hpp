// SPDX-License-Identifier: Apache-2.0
// Circle fitting on fused 2-D laser points (thesis 6.2.2, Eq. 6.7-6.8):
//
//   fit_circle_kasa      plain algebraic least squares (Kasa 1976): the
//                        cheapest fit; its radius is biased low on short arcs.
//   fit_circle_hyper     the Hyper fit (Al-Sharadqah & Chernov 2009): an
//                        algebraic fit whose essential bias is zero.
//   fit_circle_taubin    Taubin (1991), for comparison.
//   refine_circle        geometric (orthogonal distance) Levenberg-Marquardt,
//                        optionally weighted per point and with a known radius.
//                        This is the maximum-likelihood fit under Gaussian
//                        noise; it reaches the KCR bound to first order.
//   fit_circle_robust    MSAC on minimal samples (3 points, or 2 with a known
//                        radius), then Hyper fits of the consensus set,
//                        re-selected while it changes, and a final geometric
//                        refinement.
//   kcr_bound            the KCR lower bound (Chernov & Lesort 2004) of the
//                        covariance of (centre, radius) for given true points
//                        and noise.
//
// Points are the columns of a 2 x n matrix [m]. Non-finite points take no
// part (they are counted). Degenerate input (fewer than the minimum of points,
// collinear points) is a result with a status and a reason, never an
// exception.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <tinyline/common/status.hpp>

namespace tinyline::hydrus_fitting {

struct Circle {
  Eigen::Vector2d centre_m = Eigen::Vector2d::Zero();
  double radius_m = 0.0;
};

/// Why a fit failed, finer than its Status's code: the circle fitter sends
/// it on the wire (msgs::CircleFit::STATUS_*), and fit_circle tells a
/// collinear start from the others. fit_status() gives the code.
enum class FitStatus : std::uint8_t {
  kOk = 0,
  kTooFewPoints,      ///< fewer finite points than the fit needs
  kCollinear,         ///< the points lie on a line (no finite circle)
  kNoConsensus,       ///< robust fit: no hypothesis gathered enough inliers
  kRadiusOutOfRange,  ///< the best circle's radius is outside [min, max]
  kInvalidParams,     ///< a parameter is out of its range (reason names it)
};
[[nodiscard]] const char* to_string(FitStatus s);
/// The outcome of a fit ending with `detail`: ok for kOk, InvalidArgument for
/// kInvalidParams, NotFound for valid input without a circle (too few points,
/// collinear, no consensus, radius out of range).
[[nodiscard]] common::Status fit_status(FitStatus detail, std::string message);

/// Result of every circle fit. Covariance rows/cols are (cx, cy, r); with a
/// known radius the r row and column are zero.
struct CircleFit {
  common::Status status{common::StatusCode::NotFound, ""};  ///< the message says why when not ok
  FitStatus detail = FitStatus::kTooFewPoints;              ///< the finer case, kOk when ok
  Circle circle;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  ///< [m^2]; zero for the algebraic fits
  double rms_residual_m = 0.0;                           ///< RMS orthogonal distance of the points used
  int points_used = 0;                                   ///< finite points fitted (the consensus set for robust fits)
  int non_finite = 0;                                    ///< input points skipped for a NaN/inf coordinate
  int iterations = 0;                                    ///< LM iterations (refine) or hypotheses drawn (robust)
  bool converged = false;                                ///< LM met its tolerance (refine, robust)
  double radius_bias_removed_m = 0.0;  ///< subtracted from the radius (RefineParams::remove_radius_bias)
  bool second_order_applied = false;   ///< the second-order correction was asked for and its rule let it act
  double end_weight_applied = 0.0;     ///< k of the second-order end weighting (0: none)
  Eigen::Vector3d mode_shift_m = Eigen::Vector3d::Zero();  ///< (cx, cy, r) added by the second-order mode shift
  std::vector<std::uint8_t> inlier_mask;                   ///< robust fit: 1 per input point in the consensus set

  [[nodiscard]] bool ok() const { return status.ok(); }
  /// Sets status and detail together.
  void set_outcome(FitStatus d, std::string message = {}) {
    detail = d;
    status = fit_status(d, std::move(message));
  }
};

/// Kasa: minimises sum (x^2 + y^2 + D x + E y + F)^2. Biased (radius too
/// small on short arcs); kept as the reference the benchmarks compare with.
[[nodiscard]] CircleFit fit_circle_kasa(const Eigen::Ref<const Eigen::Matrix2Xd>& points);
/// Hyper fit (Al-Sharadqah & Chernov 2009, "Error analysis for circle fitting
/// algorithms", Eq. for the 'hyperaccurate' constraint matrix), SVD-free form.
[[nodiscard]] CircleFit fit_circle_hyper(const Eigen::Ref<const Eigen::Matrix2Xd>& points);
/// Taubin fit (Taubin 1991), Chernov's centred form.
[[nodiscard]] CircleFit fit_circle_taubin(const Eigen::Ref<const Eigen::Matrix2Xd>& points);

/// What refine_circle does after the geometric (maximum-likelihood) fit.
enum class ArcCorrection : std::uint8_t {
  kNone,         ///< the ML fit as it is: reaches the KCR bound to first order
  kSecondOrder,  ///< SecondOrderCorrection: less second-order error at large sigma/r on short arcs
};
[[nodiscard]] const char* to_string(ArcCorrection c);

/// Beyond the first-order (KCR) regime, at sigma/r ~ 0.1 on arcs of 90-180
/// deg, the ML fit's error is dominated by second-order terms
/// (docs/hydrus_fitting.md "Beyond first order"). Two corrections, both
/// vanishing at small noise so the fit stays the efficient one there:
///  1. End weighting: refit with weights w = 1 - k s^2 (s: a point's angle
///     from the arc's middle over the half-span), k = end_weight x (q /
///     reference_sigma_over_r)^2 up to max_end_weight, q = the residuals'
///     RMS over the fitted radius. It trades a little first-order efficiency for less of the
///     normal x tangential cross term, which is largest at the ends of a
///     short arc. Full up to full_weighting_arc_deg, none from
///     no_weighting_arc_deg (a closed circle has no ends); likewise by the
///     fit's SD(r) / r (full_/no_weighting_rel_sd_r).
///  2. Mode shift: theta -= gamma Cov(theta, r) / r (gamma = mode_shift),
///     at most max_shift_sds of the fit's own SD of r. The radius estimate
///     is about the inverse of a near-symmetric curvature estimate, so its
///     distribution leans towards large radii; the shift moves the estimate
///     towards the centre of its distribution's densest half (for a
///     Gaussian curvature, the mode of r is at r - 2 Var(r) / r), and the
///     centre with it by the regression of the centre on r. The cap keeps
///     it where that small-noise expansion holds.
/// Constants chosen on noise draws (seeds 5, 7) other than the reported ones.
struct SecondOrderCorrection {
  double end_weight = 0.6;  ///< k at sigma/r = reference_sigma_over_r (0: no refit)
  double reference_sigma_over_r = 0.13;
  double max_end_weight = 1.0;            ///< k at most (weights stay >= 5 %)
  double full_weighting_arc_deg = 150.0;  ///< end weighting fades out between these arcs [deg]
  double no_weighting_arc_deg = 240.0;
  /// ... and as the fit's relative SD of the radius, SD(r) / r, goes from
  /// the first to the second: on a short arc at high noise down-weighting
  /// its ends costs more than it buys (60 deg at 19.6 mm: 1.33 of the bound
  /// with, 1.09 without).
  double full_weighting_rel_sd_r = 0.14;
  double no_weighting_rel_sd_r = 0.20;
  double mode_shift = 2.5;     ///< gamma (0: no shift)
  double max_shift_sds = 0.5;  ///< |radius shift| <= this many SDs of the fitted radius
  /// Where the correction is applied at all (second_order_applies): only
  /// while the noise over the radius seen in the residuals, q, is at most
  /// max_sigma_over_r (and the fit has at most max_points points). From
  /// sigma/r = 0.17 on arcs of 60-180 deg it made the fit worse than the
  /// plain one at 100 and 400 points; up to 0.13 it helped or cost at most
  /// 0.04 of the bound, at 30-400 points (tuning draws, hydrus seed 100;
  /// docs/hydrus_fitting.md "Outside its design"). No point count needed a
  /// limit.
  double max_sigma_over_r = 0.15;
  int max_points = std::numeric_limits<int>::max();
};

/// The correction's applicability rule: n points fitted, q = the residuals'
/// RMS over the fitted radius.
[[nodiscard]] bool second_order_applies(const SecondOrderCorrection& so, int n, double q);

struct RefineParams {
  int max_iterations = 50;
  double step_tolerance_m = 1e-10;  ///< stop when the update is shorter than this
  double initial_lambda = 1e-3;     ///< LM damping (Marquardt, scaled by diag(J^T W J))
  /// Fix the radius to this value [m] (> 0), fitting only the centre.
  std::optional<double> known_radius_m;
  /// Covariance scale: true uses the residuals (sigma^2 = weighted RSS /
  /// (n - p)); false uses the per-point sigmas as given (a-priori).
  bool covariance_from_residuals = true;
  /// Remove the geometric fit's essential radius bias (Al-Sharadqah &
  /// Chernov 2009): noise across the normal moves points outwards on average,
  /// so r is too large by sigma_t^2 / (2 r). Assumes isotropic noise (sigma_t
  /// = the normal SD, estimated from the residuals); for noise along known
  /// rays, CircleEstimator corrects with the tangential part instead.
  bool remove_radius_bias = false;
  /// Second-order correction (not with a known radius). The covariance
  /// stays that of the ML fit (the first-order one; the corrected fit's
  /// error is within ~10 % of it where the correction acts).
  ArcCorrection correction = ArcCorrection::kNone;
  SecondOrderCorrection second_order;
};

/// Geometric fit from an initial circle. `sigma_m`, if not empty, is the
/// noise SD of each point along the circle's normal [m] (weights 1/sigma^2);
/// otherwise every point has weight 1. Needs >= 3 points (>= 2 with a known
/// radius).
/// The parameter check refine_circle makes first (second_order only when it applies).
common::Status validate(const RefineParams& params);

[[nodiscard]] CircleFit refine_circle(const Eigen::Ref<const Eigen::Matrix2Xd>& points, const Circle& initial,
                                      const RefineParams& params = {}, std::span<const double> sigma_m = {});

/// Removes the essential bias of a geometric fit (Al-Sharadqah & Chernov
/// 2009) when the noise across the circle's normal is known per point: such
/// noise moves a point outwards by sigma_t^2 / (2 r) on average, which the
/// fit turns into a radius (and, when uneven, a centre) bias. Shifts `fit`
/// by (J^T W J)^-1 J^T W b, b_i = sigma_t,i^2 / (2 r), over the points with
/// mask 1 (all when the mask is empty); weights 1/sigma_m^2 as in the fit.
/// Returns the shift (cx, cy, r) applied.
Eigen::Vector3d remove_essential_bias(const Eigen::Ref<const Eigen::Matrix2Xd>& points, CircleFit& fit,
                                      std::span<const double> sigma_m, std::span<const double> tangential_sd_m,
                                      std::span<const std::uint8_t> mask = {});

/// Hyper, then geometric refinement: the non-robust best fit.
[[nodiscard]] CircleFit fit_circle(const Eigen::Ref<const Eigen::Matrix2Xd>& points, const RefineParams& params = {},
                                   std::span<const double> sigma_m = {});

struct RobustCircleParams {
  /// Orthogonal distance under which a point supports a circle [m]; about 3x
  /// the range noise (Table 3.1: 0.4-1 cm SD at 0.2-1 m).
  double inlier_threshold_m = 0.02;
  /// With per-point sigmas (sigma_m), a point supports a circle only within
  /// this many of its own sigma (and within inlier_threshold_m), and MSAC
  /// scores residuals in sigma units. 0: the absolute threshold alone.
  double inlier_threshold_sigmas = 3.0;
  /// Accepted radii [m]; hypotheses outside are skipped, a final fit outside
  /// is kRadiusOutOfRange.
  double min_radius_m = 0.01;
  double max_radius_m = 2.0;
  /// Fit only the centre for this radius [m] (2-point minimal samples).
  std::optional<double> known_radius_m;
  int max_iterations = 1000;          ///< hypotheses at most
  double confidence = 0.999;          ///< adaptive stop: P(an all-inlier sample was drawn)
  int min_inliers = 5;                ///< a consensus set smaller than this is kNoConsensus
  int local_optimisation_rounds = 3;  ///< Hyper fit of the set, re-select, at most this often
  /// After each local-optimisation fit the consensus set is
  /// re-selected with the tighter of inlier_threshold_m and this many robust
  /// SDs of its own residuals (1.4826 MAD, per-point sigmas normalised out),
  /// so clutter just inside a generous threshold cannot hold the fit (three
  /// extra rounds allowed for it). 0 disables.
  double final_threshold_sigmas = 3.0;
  std::uint64_t seed = 1;  ///< sampling is deterministic for a seed
  /// End with the geometric (LM) fit of the consensus set, which gives the
  /// covariance. Off: the algebraic fit of the last round is returned (no
  /// covariance), for callers that refit the inliers themselves.
  bool final_geometric_fit = true;
  RefineParams refine;  ///< known_radius_m here is ignored: set it above
};

/// Where each point was seen from (optional): a hypothesis is only supported
/// by points that face their sensor (the surface normal points towards the
/// viewpoint), and is rejected when a viewpoint lies inside it. This removes
/// circles through points a sensor could not have seen (the far side of the
/// object, points on the robot behind the sensor).
struct Viewpoints {
  std::span<const Eigen::Vector2d> origins_m;  ///< per sensor
  std::span<const int> sensor_of_point;        ///< per point: index into origins_m
};

/// MSAC + local optimisation. `sigma_m` as in refine_circle (per point).
/// The parameter check fit_circle_robust makes first.
common::Status validate(const RobustCircleParams& params);

[[nodiscard]] CircleFit fit_circle_robust(const Eigen::Ref<const Eigen::Matrix2Xd>& points,
                                          const RobustCircleParams& params = {}, std::span<const double> sigma_m = {},
                                          const Viewpoints& viewpoints = {});

/// Result of kcr_bound: the covariance (cx, cy, r) no unbiased estimator can
/// beat to first order in the noise (Chernov & Lesort 2004): sigma^2
/// (sum_i g_i g_i^T / sigma_i^2)^-1 with g_i = d(|p_i - c| - r)/d(cx, cy, r) at
/// the true circle. With a known radius, the 2 x 2 centre block (r terms zero).
struct KcrBound {
  common::Status status;  ///< InvalidArgument: bad sigma or points, or a singular information matrix
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  ///< [m^2]
};
/// `true_points` lie on `truth`; `sigma_m` is one SD for all points (size 1)
/// or one per point, along the normal [m].
[[nodiscard]] KcrBound kcr_bound(const Eigen::Ref<const Eigen::Matrix2Xd>& true_points, const Circle& truth,
                                 std::span<const double> sigma_m, bool known_radius = false);

/// Circle through three points; nullopt when they are (nearly) collinear.
[[nodiscard]] std::optional<Circle> circle_through(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                                                   const Eigen::Vector2d& c);

}  // namespace tinyline::hydrus_fitting
