// SPDX-License-Identifier: Apache-2.0
// A structured-light RGB-D camera (the Xtion / Carmine of thesis 4.2.3) in
// the simulated world: a pinhole camera with a z-buffer (ray cast per pixel),
// depth registered to the colour image, and the artefacts that make real
// structured-light clouds hard to segment:
//   - depth noise growing with the square of range (the disparity error
//     divided by f*b/z^2), split into a per-pixel part and a part correlated
//     over the matching window, plus disparity quantisation;
//   - missing depth where the projector cannot see the surface (its shadow
//     beside near objects), at silhouette edges (the matching window spans a
//     depth jump), at grazing incidence, and out of the working range;
//   - colours from a lit scene (ambient + one lamp with shadows + a glossy
//     highlight on skins that have one), sRGB-encoded with sensor noise, so
//     that red tomatoes pass the HSI filter of thesis 4.3.1 and leaves,
//     stems, pedicels and highlights do not;
//   - an optional systematic depth distortion (the residual of the factory
//     calibration that Eq. 4.4 corrects).
//
// Frames: the camera's optical frame (x right, y down, z forward), placed in
// the world with T_world_camera. The projector sits at (projector_baseline_m,
// 0, 0) in that frame.
//
// Core code: no bus, no I/O. Deterministic for a given seed and frame index.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <sim/world.hpp>

#include <tinyline/common/status.hpp>

namespace tinyline::sim {

struct PinholeIntrinsics {
  int width = 640;    ///< [px] VGA
  int height = 480;   ///< [px]
  double fx = 570.3;  ///< [px] (58 deg horizontal field of view at VGA, as the Xtion/Carmine)
  double fy = 570.3;  ///< [px]
  double cx = 319.5;  ///< [px]
  double cy = 239.5;  ///< [px]

  /// Unit ray through the centre of pixel (u, v) in the optical frame.
  [[nodiscard]] Eigen::Vector3d ray(double u, double v) const {
    return Eigen::Vector3d((u - cx) / fx, (v - cy) / fy, 1.0).normalized();
  }
};

/// Depth distortion left after the factory calibration, as Eq. 4.4 models it:
/// z_measured = z + Z(u, v) + theta(z), with Z a quadratic in the normalised
/// image coordinates (xn = (u - cx) / width, yn = (v - cy) / height) and
/// theta linear in z. All coefficients in metres (per metre for `z_slope`).
struct DepthDistortion {
  /// Z(u, v) = c0 + c1 xn + c2 yn + c3 xn^2 + c4 xn yn + c5 yn^2 [m]
  std::array<double, 6> spatial_m{0, 0, 0, 0, 0, 0};
  double z_slope = 0.0;  ///< theta(z) = z_slope * z [m per m]

  [[nodiscard]] bool enabled() const;
  [[nodiscard]] double offset_m(double xn, double yn, double z_m) const;
};

/// A material whose colour has a glossy highlight (skin of a tomato).
struct Gloss {
  std::string material_prefix = "tomato";  ///< applies to every material whose name starts with this
  double strength = 0.3;                   ///< white specular weight at the lobe's peak [0, 1]
  double exponent = 30.0;                  ///< Blinn-Phong exponent (larger = smaller highlight)
};

struct RgbdCameraParams {
  PinholeIntrinsics intrinsics;
  double min_depth_m = 0.35;            ///< no depth nearer than this (Carmine 1.09 short range)
  double max_depth_m = 3.5;             ///< ... or farther
  double projector_baseline_m = 0.075;  ///< projector offset along +x of the optical frame

  // Depth noise. The depth error of a structured-light camera comes from the
  // disparity error sigma_d [px]: sigma_z = z^2 sigma_d / (f b).
  double disparity_noise_px = 0.07;             ///< per-pixel part [px rms]
  double disparity_noise_correlated_px = 0.05;  ///< part shared over the matching window [px rms]
  int correlation_window_px = 9;                ///< matching window (correlated part's length scale) [px]
  double disparity_step_px = 0.125;             ///< quantisation of the disparity (1/8 px)

  // Missing depth.
  bool projector_shadow = true;     ///< no depth where the projector cannot see the point
  double edge_jump_m = 0.02;        ///< a depth jump larger than this inside the 3x3 window...
  double edge_jump_per_m = 0.02;    ///< ... plus this times the range, is a silhouette edge
  double edge_dropout = 0.85;       ///< probability of losing depth at a silhouette edge pixel
  double grazing_start_deg = 70.0;  ///< beyond this incidence the pattern starts to fade...
  double grazing_end_deg = 85.0;    ///< ... and beyond this no depth is returned

  // Colour.
  Eigen::Vector3d light_position_m{0.3, -0.2, 1.2};   ///< lamp in the world frame [m]
  double light_intensity = 1.15;                      ///< diffuse irradiance scale of the lamp at normal incidence
  double ambient = 0.30;                              ///< ambient (indirect) light scale
  bool shadows = true;                                ///< the lamp's shadows (one shadow ray per pixel)
  double exposure = 1.0;                              ///< linear gain before sRGB encoding
  double colour_noise_dn = 1.5;                       ///< sensor noise per channel [8-bit counts rms]
  std::vector<Gloss> gloss{Gloss{}};                  ///< glossy materials
  Eigen::Vector3d background_rgb{0.02, 0.02, 0.025};  ///< where a ray hits nothing (linear)

  DepthDistortion distortion;  ///< off by default
  std::uint64_t seed = 1;
  /// Cast each 16x16 tile against only the objects that can appear in it
  /// (same frame, several times faster); false casts every ray at the
  /// whole world (the reference the benchmark compares with).
  bool tile_culling = true;

  /// Why the parameters cannot work (InvalidArgument); ok when they can.
  common::Status validate() const;
};

/// One registered RGB-D frame. Pixel (u, v) is index v * width + u.
struct RgbdFrame {
  int width = 0;
  int height = 0;
  PinholeIntrinsics intrinsics;
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
  std::vector<float> depth_m;                    ///< z along the optical axis; NaN: no depth
  std::vector<std::array<std::uint8_t, 3>> rgb;  ///< sRGB colour, 8 bit
  std::vector<ObjectId> object;                  ///< ground truth: object seen (kNoObject: none)
  std::vector<float> true_depth_m;               ///< ground truth z before noise (NaN: nothing hit)

  [[nodiscard]] std::size_t size() const { return depth_m.size(); }
  [[nodiscard]] bool valid(std::size_t i) const { return depth_m[i] == depth_m[i]; }
  /// The 3-D point of pixel i in the optical frame (NaN when it has no depth).
  [[nodiscard]] Eigen::Vector3f point(std::size_t i) const;
  [[nodiscard]] std::size_t num_valid() const;
};

class RgbdCamera {
 public:
  /// Throws std::invalid_argument naming the first bad parameter.
  explicit RgbdCamera(RgbdCameraParams params = {});

  [[nodiscard]] const RgbdCameraParams& params() const { return params_; }

  /// Renders one frame. `frame_index` seeds the frame's noise (same index,
  /// same frame).
  [[nodiscard]] RgbdFrame render(const World& world, const Eigen::Isometry3d& T_world_camera,
                                 std::uint64_t frame_index = 0) const;

  /// Projects a point of the optical frame to pixel coordinates (u, v);
  /// false when it lies behind the camera.
  [[nodiscard]] bool project(const Eigen::Vector3d& p_camera, Eigen::Vector2d& uv) const;

 private:
  RgbdCameraParams params_;
};

/// Optical frame looking from `eye` at `target` with world +z up on screen
/// (the camera's y axis points as far down as it can).
[[nodiscard]] Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                                        const Eigen::Vector3d& up = Eigen::Vector3d::UnitZ());

/// sRGB encoding of a linear value in [0, 1] to [0, 255].
[[nodiscard]] double srgb_encode(double linear);

}  // namespace tinyline::sim
