// SPDX-License-Identifier: Apache-2.0
// Sphere segmentation (thesis 4.3.2, Eq. 4.10-4.15): iterative RANSAC for
// spheres within a radius range. Each round samples hypotheses, keeps the
// one with the most inliers, refines it, stores it and removes its inliers;
// rounds stop when too few points remain or no model is found.
//
// Hypotheses (compared in docs/tomato_reasoning.md by measurement):
//   kFourPoints             4 points, the sphere through them (Eq. 4.10, 4.11;
//                           coplanar samples are degenerate);
//   kTwoPointsWithNormals   2 points and their normals (Eq. 4.12): the centre
//                           halfway along the shortest segment between the
//                           normal lines, the radius the mean distance.
// The points of one hypothesis are drawn near the first (within the largest
// diameter): the chance that all lie on one tomato, P(k) of Eq. 4.13-4.14,
// then no longer falls as (n/N)^k with the number of tomatoes in the cloud.
// Sampling stops early at the confidence of Eq. 4.15.
//
// A model is refused when its visible cap faces away from the camera (the
// centre of its inliers lies beyond the sphere's centre: the camera sees
// only the near half of a tomato), when it reaches deep into an accepted
// sphere (two fruit cannot interpenetrate), or when too few points support
// it. Each model is refined by geometric least squares (distance to the
// surface) with the radius held inside the range; PCL's own refinement
// (optimizeModelCoefficients) leaves the radius free and can leave the range,
// which SphereRefinement.GeometricFitStaysInsideTheRadiusRangeWherePclLeavesIt shows.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "tomato_reasoning/cloud.hpp"

#include <tinyline/common/status.hpp>

namespace tinyline::tomato_reasoning {

struct Sphere {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< [m]
  double radius_m = 0.0;
};

/// The sphere through four points; nullopt when they are (nearly) coplanar
/// or the solution is not finite.
[[nodiscard]] std::optional<Sphere> sphere_from_four_points(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                                            const Eigen::Vector3d& c, const Eigen::Vector3d& d);
/// Eq. 4.12: from two points and their unit normals; nullopt when the normal
/// lines are (nearly) parallel.
[[nodiscard]] std::optional<Sphere> sphere_from_two_points_with_normals(const Eigen::Vector3d& p1,
                                                                        const Eigen::Vector3d& n1,
                                                                        const Eigen::Vector3d& p2,
                                                                        const Eigen::Vector3d& n2);

struct SphereRefinement {
  Sphere sphere;
  bool converged = false;
  bool radius_at_limit = false;  ///< the best radius inside the range is a limit of it
  int iterations = 0;
  double rms_m = 0.0;  ///< RMS distance of the points to the surface
};

/// Geometric least squares, min sum (|p - c| - r)^2 with r in [r_min, r_max]
/// (Levenberg-Marquardt; when the free optimum leaves the range, r is held
/// at the limit and c refitted).
[[nodiscard]] SphereRefinement refine_sphere(const std::vector<Eigen::Vector3f>& points, const Indices& indices,
                                             const Sphere& initial, double r_min, double r_max);

enum class SphereHypothesis { kFourPoints, kTwoPointsWithNormals };
[[nodiscard]] const char* to_string(SphereHypothesis h);

struct SphereRansacParams {
  double radius_min_m = 0.025;  ///< tomato radius range [m] (thesis tomatoes 2.5-4 cm)
  double radius_max_m = 0.040;
  double inlier_distance_m = 0.004;  ///< |distance to the surface| of an inlier [m]
  /// An inlier's normal must lie within this of the sphere's radial
  /// direction [deg]; <= 0 turns the test off (no normals needed).
  double normal_tolerance_deg = 35.0;
  SphereHypothesis hypothesis = SphereHypothesis::kTwoPointsWithNormals;
  int max_iterations = 300;    ///< hypotheses per round at most
  double confidence = 0.995;   ///< Eq. 4.15 early stop: P(at least one all-inlier sample)
  bool local_sampling = true;  ///< draw a hypothesis's other points near its first
  int min_inliers = 40;        ///< a model needs this many inliers
  int min_remaining = 40;      ///< stop when fewer points remain
  int max_spheres = 12;
  int max_failed_rounds = 3;     ///< stop after this many rounds in a row without a model
  double max_overlap_m = 0.008;  ///< a new sphere may reach this far into an accepted one [m]
  /// Points within this many inlier distances of an accepted sphere (and
  /// facing along its radius) are removed with it.
  double removal_factor = 1.5;
  bool refine = true;      ///< geometric least squares within the radius range
  std::uint64_t seed = 1;  ///< sampling is reproducible
};

common::Status validate(const SphereRansacParams& p);

struct SphereFit {
  Sphere sphere;
  Indices inliers;  ///< into the input points
  double rms_m = 0.0;
  bool radius_at_limit = false;
  /// Cosine between the sphere-to-camera direction and the sphere-to-inlier-
  /// centroid direction (the best of the viewpoints): > 0 means the visible
  /// cap faces the camera.
  double cap_facing = 0.0;
  int round = 0;  ///< the round that found it
  /// Depth noise along the rays measured around this sphere [m rms] (0: not
  /// measured) and the sphere as the segmentation found it, before the noise
  /// bias was corrected (`sphere` is corrected when the pipeline does it).
  double depth_noise_m = 0.0;
  Sphere uncorrected;
};

struct SphereSegmentation {
  std::vector<SphereFit> spheres;
  int rounds = 0;
  long hypotheses = 0;       ///< samples drawn, all rounds
  long degenerate = 0;       ///< samples without a sphere (coplanar, parallel normals, out of range)
  int rejected_cap = 0;      ///< best models refused because the cap faced away
  int rejected_overlap = 0;  ///< ... because they reached into an accepted sphere
  int remaining_points = 0;
  /// Not ok when nothing could be done: InvalidArgument for bad parameters,
  /// no viewpoint or missing normals, NotFound for too few usable points.
  common::Status status;
  std::string stop_reason;  ///< a note on why the rounds stopped (when they ran)
};

/// Segments spheres among `points` (with `normals`, required for
/// kTwoPointsWithNormals or a normal tolerance; may be empty otherwise).
/// The camera sits at `viewpoint`.
[[nodiscard]] SphereSegmentation segment_spheres(const std::vector<Eigen::Vector3f>& points,
                                                 const std::vector<Eigen::Vector3f>& normals,
                                                 const SphereRansacParams& params = {},
                                                 const Eigen::Vector3f& viewpoint = Eigen::Vector3f::Zero());
/// The same for points merged from several views: a cap must face at least
/// one of the `viewpoints`.
[[nodiscard]] SphereSegmentation segment_spheres(const std::vector<Eigen::Vector3f>& points,
                                                 const std::vector<Eigen::Vector3f>& normals,
                                                 const SphereRansacParams& params,
                                                 const std::vector<Eigen::Vector3f>& viewpoints);

/// The bias a fit to a noisy cap seen from one side keeps (docs/tomato_reasoning.md,
/// "Sphere bias under depth noise"): the sphere comes out too small and too
/// near the camera, by amounts that grow with the depth noise's variance.
/// Measured against truth on tuning trusses, it is corrected as
///   r += radius_bias_m + radius_per_var * sigma^2,
///   c += (centre_bias_m + centre_per_var * sigma^2) * (away from the cameras),
/// sigma the noise along the rays measured on the raw points of the sphere's
/// front (robust: the median absolute deviation of their range to the front).
struct NoiseBiasParams {
  bool enabled = true;    ///< false: the segmentation's spheres as found
  double band_m = 0.015;  ///< raw points within this of the front along their ray [m]
  double min_cos = 0.5;   ///< rays meeting the surface at least this squarely (not the limb)
  int min_points = 20;    ///< fewer: no noise measured, no correction
  /// Fitted on tuning trusses 1-40 (elastic rods, one and two views, 0-5 mm
  /// extra noise, a common slope per view count's intercept); the intercepts
  /// differ by view count (one view -0.5 mm radius, two +0.2 mm) and stay 0.
  double radius_bias_m = 0.0;     ///< radius added at zero noise [m]
  double radius_per_var = 96.0;   ///< radius added per noise variance [1/m] (0.096 mm per mm^2)
  double centre_bias_m = 0.0;     ///< centre moved away from the cameras at zero noise [m]
  double centre_per_var = 134.0;  ///< ... per noise variance [1/m]
};

common::Status validate(const NoiseBiasParams& p);

struct DepthNoise {
  double sigma_m = 0.0;                            ///< along the rays [m rms]
  int points = 0;                                  ///< front points it was measured on
  Eigen::Vector3d away = Eigen::Vector3d::Zero();  ///< unit, from the cameras through the centre (their mean)
};

/// The depth noise around `sphere` on raw points (seen from
/// viewpoints[view_of[k]]); `points` 0 when too few lie on its front.
[[nodiscard]] DepthNoise measure_depth_noise(const std::vector<Eigen::Vector3f>& points,
                                             const std::vector<std::uint8_t>& view_of,
                                             const std::vector<Eigen::Vector3f>& viewpoints, const Sphere& sphere,
                                             const NoiseBiasParams& params = {});

/// `sphere` with the bias of `noise` removed (unchanged when nothing was
/// measured); the radius stays within [r_min, r_max].
[[nodiscard]] Sphere correct_noise_bias(const Sphere& sphere, const DepthNoise& noise, const NoiseBiasParams& params,
                                        double r_min, double r_max);

}  // namespace tinyline::tomato_reasoning
