// SPDX-License-Identifier: Apache-2.0
// A tomato truss close up, as the harvesting gripper's laser sees it (thesis
// 4.5, Table 4.3; laser_clustering's evaluation): straight pedicels as thin
// rods hanging within a tilt of vertical from the truss's main stem (a chain
// of rods, straight or bowed), a spherical tomato at each one's end, the
// target's neighbours along the stem on both sides, and maybe a leaf wall
// behind. Nothing settles: the few centimetres around one pedicel that the
// laser plane cuts, where truss.hpp's settled truss is the camera's whole
// truss. Both are built here, in sim, and nowhere else.
//
// Frame: the gripper laser's nominal observation pose: z forward, x along the
// laser line, y = z cross x (down); the laser plane is y = 0.
#pragma once

#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <sim/world.hpp>

namespace tinyline::sim {

/// Placing things in a close-up scene (this truss, laser_clustering's gripper
/// and tool scenes): a pose from a translation and a rotation, a rotation
/// about an axis, and a material by name (`who` names the scene in the error).
[[nodiscard]] inline Eigen::Isometry3d pose(const Eigen::Vector3d& t,
                                            const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}
[[nodiscard]] inline Eigen::Matrix3d rot(const Eigen::Vector3d& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}
[[nodiscard]] inline MaterialId material(const World& w, const std::string& name, const char* who) {
  const auto id = w.materials().find(name);
  if (!id) throw std::invalid_argument(std::string(who) + ": unknown material '" + name + "'");
  return *id;
}

/// The close-up scenes' draws: std::mt19937_64 through the standard
/// distributions. Kept because the evaluation's documented figures come from
/// these draws; new scenes draw from <tinyline/common/random.hpp>.
struct SceneRng {
  explicit SceneRng(std::uint64_t seed) : gen(seed) {}
  double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(gen); }
  double uniform(const double (&r)[2]) { return uniform(r[0], r[1]); }
  double normal(double sd) { return std::normal_distribution<double>(0.0, sd)(gen); }
  int integer(int a, int b) { return std::uniform_int_distribution<int>(a, b)(gen); }
  std::mt19937_64 gen;
};

struct CloseTrussParams {
  double vertical_jitter_m = 0.008;  ///< where along the target pedicel the laser plane cuts, around its middle [m]
  double max_tilt_deg = 15.0;        ///< pedicels hang within this of vertical (up to 60)
  /// A curved stem: the pedicel tops leave the straight line through the
  /// target's top by stem_bow_m (dx / 10 cm)^2 at dx along it, in a direction
  /// across the stem drawn per scene from its own stream. 0: straight.
  double stem_bow_m = 0.0;
  double pedicel_radius_m[2] = {0.0025, 0.0035};
  double pedicel_length_m[2] = {0.03, 0.05};
  double tomato_radius_m[2] = {0.025, 0.035};
  double neighbour_spacing_m[2] = {0.045, 0.085};  ///< along the stem between pedicel tops
  double neighbour_depth_m = 0.025;                ///< neighbours sit up to this before/behind the target [m]
  double neighbour_drop_m = 0.02;                  ///< neighbours' tops up to this above/below the target's [m]
  double leaf_probability = 0.6;                   ///< a leaf wall behind the truss
  /// The leaf wall's depth when the target is 0.15 m ahead; it moves with
  /// the target's nominal depth [m].
  double leaf_z_m[2] = {0.30, 0.60};
};

/// One pedicel with its tomato.
struct HangingTomato {
  Eigen::Vector3d top, bottom, dir;  ///< the pedicel's ends; dir: unit, from top to bottom
  double radius = 0, length = 0;     ///< the pedicel's [m]
  Eigen::Vector3d tomato_centre;
  double tomato_radius = 0;
  ObjectId pedicel = kNoObject, tomato = kNoObject;  ///< their objects in the world
};

struct CloseTruss {
  std::vector<HangingTomato> hangings;  ///< the target first
  ObjectId stem = kNoObject;            ///< the first rod of the stem chain (named stem0, stem1, ...)
};

/// Adds a close-up truss to `world`: the target pedicel crosses the laser
/// plane at `crossing_m` (somewhere around its middle), neighbours hang on
/// both sides (at least one in all), the stem runs through every top and
/// 10 cm beyond the outer ones, and a leaf wall stands behind with
/// probability p.leaf_probability (nominal_depth_m: the target's nominal
/// depth, which the wall follows). Draws from `rng` in a fixed order, so the
/// caller's draws before and after stay as they were; `seed` keys the stem
/// bow's own stream.
[[nodiscard]] CloseTruss add_close_truss(World& world, SceneRng& rng, std::uint64_t seed,
                                         const Eigen::Vector3d& crossing_m, double nominal_depth_m,
                                         const CloseTrussParams& p);

}  // namespace tinyline::sim
