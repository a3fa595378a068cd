// SPDX-License-Identifier: Apache-2.0
// Synthetic planar scans for tests, benchmarks and the Monte-Carlo studies:
// every pixel of every sensor on the robot ray-traced in the sensing plane
// against cylinders, walls and the robot's own links, with the range noise
// of Table 3.1 along the ray. (The physics simulator, sim/, is the full
// model; this is the exact-geometry reference with controlled noise.)
#pragma once

#include <string>
#include <vector>

#include "hydrus_fitting/circle_fit.hpp"
#include <tinyline/common/random.hpp>
#include "hydrus_fitting/fusion.hpp"
#include "hydrus_fitting/robot_model.hpp"
#include "hydrus_fitting/sequencer.hpp"

namespace tinyline::hydrus_fitting::eval {

struct PlanarWorld {
  std::vector<Circle> cylinders;
  std::vector<Capsule> obstacles;   ///< walls, boxes as thick segments
  bool robot_links_visible = true;  ///< the sensors see the robot's own links
};

struct SyntheticScanParams {
  int pixels = 256;          ///< effective pixels across the lens's field of view
  RangeNoiseModel noise;     ///< SD along the ray vs range
  double noise_scale = 1.0;  ///< multiplies the SD (0: exact ranges)
};

enum HitKind : int { kHitNone = -1, kHitCylinder = 0, kHitObstacle = 1, kHitRobot = 2 };

struct SyntheticScan {
  std::string sensor;
  std::vector<double> angle_rad, range_m;  ///< NaN range: nothing within range
  std::vector<int> hit_kind;               ///< HitKind per pixel
  std::vector<int> hit_index;              ///< which cylinder / obstacle / link
  std::vector<double> true_range_m;
};

/// Pixel angles of a sensor: atan(u / f), u the pixel centres over the line.
std::vector<double> pixel_angles(const SensorSpec& s, int pixels);

/// The scans of every sensor of `model` at joint angles `q`.
std::vector<SyntheticScan> scan_all(const RobotModel& model, const std::vector<double>& q, const PlanarWorld& world,
                                    const SyntheticScanParams& params, common::SplitMixRandom& rng);

}  // namespace tinyline::hydrus_fitting::eval
