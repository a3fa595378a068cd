// SPDX-License-Identifier: Apache-2.0
// Simulated test material for the tomato pipeline: a truss of a complexity
// class rendered by the RGB-D camera, as the pipeline's cloud and with the
// truth in the camera's frame. Used by the tests, the scoring tool and the
// benchmarks (not part of the core: it depends on the simulator).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

#include <sim/rgbd_camera.hpp>
#include <sim/scenes/truss.hpp>

#include "tomato_reasoning/cloud.hpp"

namespace tinyline::tomato_reasoning::eval {

/// An organised cloud in the camera's optical frame (NaN where no depth).
[[nodiscard]] ColorCloud to_cloud(const sim::RgbdFrame& frame);

struct TruthTomato {
  Eigen::Vector3d centre_m;  ///< camera frame
  double radius_m = 0;
  Eigen::Vector3d pedicel_dir;  ///< camera frame, unit
  Eigen::Vector3d pedicel_force_n;
  int visible_pixels = 0;      ///< pixels of the first frame that see this fruit
  int visible_pixels_any = 0;  ///< ... of the view that sees most of it
  int edges = 0;               ///< fruit-fruit contacts
};

struct ScenarioOptions {
  /// Hand-camera views: 1, or 2 as the thesis's robot took (4.5); the second
  /// orbits the truss by `second_view_yaw_deg` at the same distance and height.
  int views = 1;
  double second_view_yaw_deg = 35.0;
  /// What the pipeline is told about the second view's pose is off by this
  /// much (the residual of the hand-camera calibration and kinematics).
  double pose_noise_m = 0.0015;
  double pose_noise_deg = 0.2;
  sim::RgbdCameraParams camera;
  /// Test conditions applied to the rendered frames, not the camera model:
  /// Gaussian depth noise of this standard deviation along each pixel's ray
  /// [m] on top of the camera's own (the frames-from-disk check's 2 and 5 mm),
  /// and no depth on pixels that see a pedicel or calyx (a camera that loses
  /// every thin structure).
  double extra_depth_noise_m = 0.0;
  bool drop_pedicel_depth = false;
  /// The world's truss options (physics, scene ranges); class and seed are
  /// set per truss.
  sim::TrussParams truss;
};

struct Scenario {
  sim::TrussClass complexity = sim::TrussClass::kB;
  std::uint64_t seed = 0;
  sim::Truss truss;
  sim::World world;
  /// Views; the first camera's optical frame is the reference frame of
  /// everything below.
  std::vector<sim::RgbdFrame> frames;
  std::vector<ColorCloud> clouds;
  std::vector<Eigen::Isometry3d> T_ref_camera;  ///< as the pipeline is told (with the pose noise)
  std::vector<TruthTomato> truth;               ///< reference frame, in the truss's order
  std::vector<Eigen::Vector3d> distractors;     ///< the second branch's fruit, reference frame
  std::vector<std::pair<int, int>> contacts;    ///< fruit-fruit contacts (truth indices)
  Eigen::Vector3d gravity_camera;               ///< unit gravity in the reference frame

  [[nodiscard]] const sim::RgbdFrame& frame() const { return frames.front(); }
  [[nodiscard]] const ColorCloud& cloud() const { return clouds.front(); }
};

/// View `view` of a scenario rendered again as frame `frame_index` (its own
/// camera noise), with the options' test conditions: one of N frames of the
/// same scene.
[[nodiscard]] ColorCloud render_again(const Scenario& s, const ScenarioOptions& options, std::size_t view,
                                      std::uint64_t frame_index);

/// Builds the truss of (class, seed) and renders it from its hand-camera pose(s).
[[nodiscard]] Scenario make_scenario(sim::TrussClass complexity, std::uint64_t seed,
                                     const ScenarioOptions& options = {});

}  // namespace tinyline::tomato_reasoning::eval
