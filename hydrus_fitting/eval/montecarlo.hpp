// Monte-Carlo studies behind docs/hydrus_fitting.md.
//
//  kcr_study         circle fits against the KCR lower bound (Chernov &
//                    Lesort 2004) over arcs and noise levels: for fixed true
//                    points, many noise draws; per method and parameter the
//                    robust RMS error (1.4826 x median |error|, so heavy
//                    tails do not dominate) over the bound's SD.
//  robustness_study  four sensors on the Hydrus around a cylinder, with
//                    clutter and the robot's own links in view, so that
//                    about 40% of the fused points are outliers: success
//                    rate of the plain fit, MSAC, and MSAC with viewpoints
//                    and the self-filter.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "hydrus_fitting/circle_fit.hpp"
#include "hydrus_fitting/robot_model.hpp"

namespace tinyline::hydrus_fitting::eval {

enum class Method { kKasa, kHyper, kGeometric, kGeometricUnbiased, kRobust, kKnownRadius };
const char* to_string(Method m);

struct KcrStudyParams {
  std::vector<double> arcs_deg{30, 45, 60, 90, 120, 180, 270, 360};
  /// Table 3.1 SDs at 20.5, 50, 100, 125 cm [m].
  std::vector<double> sigmas_m{0.003625, 0.006164, 0.010480, 0.019593};
  std::vector<Method> methods{Method::kKasa,   Method::kHyper,  Method::kGeometric, Method::kGeometricUnbiased,
                              Method::kRobust, Method::kKnownRadius};
  double radius_m = 0.15;
  int points = 100;          ///< evenly spaced over the arc
  int trials = 2000;
  std::uint64_t seed = 1;
};

struct KcrRow {
  double arc_deg = 0, sigma_m = 0;
  Method method = Method::kGeometric;
  int trials = 0, failed = 0;
  double kcr_sd[3] = {0, 0, 0};       ///< sqrt of the bound's diagonal (cx, cy, r) [m]
  double rmse[3] = {0, 0, 0};         ///< 1.4826 median |error| (around the truth) [m]
  double spread[3] = {0, 0, 0};       ///< 1.4826 MAD around the median [m]
  double bias[3] = {0, 0, 0};         ///< median error [m]
  double ratio[3] = {0, 0, 0};        ///< rmse / kcr_sd
  double reported_sd_ratio[3] = {0, 0, 0};  ///< median reported SD / kcr_sd (geometric fits)
};

std::vector<KcrRow> kcr_study(const KcrStudyParams& p);
std::string kcr_csv(const std::vector<KcrRow>& rows);

struct RobustnessParams {
  std::string robot_description;   ///< the hydrus4.yaml path
  int trials = 300;
  double joint_deg = 80.0;         ///< every joint (a partly closed ring)
  double radius_m = 0.08;
  /// Small cylinders (2.5-4.5 cm radius) near the target; one set of rows per entry.
  std::vector<int> clutter_objects{0, 1, 2, 3, 4, 5};
  std::uint64_t seed = 1;
};

struct RobustnessRow {
  std::string method;              ///< plain | msac | msac_views | ...
  int clutter_objects = 0;
  int trials = 0;
  int ok = 0;                      ///< fits returned
  int correct = 0;                 ///< centre and radius both within 1 cm
  int trials_over_40 = 0;          ///< trials whose fit input was >= 40% outliers
  int correct_over_40 = 0;         ///< ... and were fitted correctly
  double median_centre_error_m = 0;
  double median_outlier_fraction = 0;  ///< of the fused points offered to the fit
};

std::vector<RobustnessRow> robustness_study(const RobustnessParams& p);

/// The whole estimator on the Hydrus's own geometry: four sensors around a
/// cylinder, Table 3.1 range noise along each pixel's ray (scaled), against
/// the KCR bound of the same true points with each point's noise across the
/// surface, sigma_r cos(incidence). Estimator variants show what each step
/// of CircleEstimator buys.
struct RayNoiseParams {
  std::string robot_description;
  std::vector<double> joint_deg{30, 60, 90};
  std::vector<double> noise_scale{1.0, 2.0, 4.0};
  double radius_m = 0.12;
  int trials = 1000;
  std::uint64_t seed = 1;
};

struct RayNoiseRow {
  double joint_deg = 0, noise_scale = 0;
  std::string variant;             ///< kasa | msac | msac_incidence | estimator (incidence + bias removal)
  int points = 0;                  ///< true points on the cylinder
  double arc_deg = 0;              ///< angular extent covered (union over the sensors)
  int trials = 0, failed = 0;
  double kcr_sd[3] = {0, 0, 0};
  double rmse[3] = {0, 0, 0};
  double bias[3] = {0, 0, 0};
  double ratio[3] = {0, 0, 0};
};

std::vector<RayNoiseRow> ray_noise_study(const RayNoiseParams& p);
std::string ray_noise_csv(const std::vector<RayNoiseRow>& rows);
std::string robustness_csv(const std::vector<RobustnessRow>& rows);

}  // namespace tinyline::hydrus_fitting::eval
