// SPDX-License-Identifier: Apache-2.0
// Tomato trusses (thesis 4.3, 4.5, Figure 4.8): 1 to 8 tomatoes hanging from
// pedicels off a peduncle, settled in static equilibrium under gravity and
// contact, with leaves and stems, in the three complexity classes of 4.5:
//   A  simple:  1-2 tomatoes, no occlusion
//   B  normal:  3-4 tomatoes, slight occlusion
//   C  complex: 5-8 tomatoes, densely gathered and occluded
//
// Physics (what the reasoning of 4.3.3 inverts). Each tomato is a rigid
// sphere of density `density_kg_m3` hanging from its anchor on the peduncle
// by a pedicel of fixed length that joins the fruit at the calyx, so the
// centre lies on the pedicel line at pedicel_length + radius from the anchor
// (a pendulum with 2 degrees of freedom). The pedicel resists bending at the
// anchor with a torsion spring towards a rest direction (real pedicels are
// stiff near the knuckle, so a lone tomato does not hang plumb). Tomatoes
// push each other and the peduncle through frictionless contacts (forces
// along the line of centres). The rest state minimises
//   sum_i m_i g z_i + 1/2 k_i angle(d_i, rest_i)^2
// subject to no interpenetration; it is found by a constrained relaxation
// (projected gradient steps on the pendulum directions with stiff contact
// penalties, continued until every tomato's net torque vanishes), and the
// contact forces at the rest state are the ground truth of Eq. 4.18-4.22.
//
// A second physics, `physics = kElasticRod` (scenes/truss_rod.hpp), is NOT
// the model the reasoning inverts: pedicels and the peduncle are discretised
// elastic rods (bending stiffness E I from a Young's modulus and the 6 mm /
// 9 mm round sections), so pedicels curve, the fruit's axis is the pedicel's
// tangent at the calyx rather than the anchor -> centre line, and the
// peduncle sags under the fruit; fruit touch with penalty contacts and
// Coulomb friction (forces off the line of centres); the rest state comes
// from a damped dynamic settle. The layout draws are the same as the
// pendulum world's, so a seed gives the same truss before settling.
//
// World frame: z up. The truss hangs in front of a hand camera that looks
// along +y from about 0.45 m (thesis hand-camera range 0.35-0.6 m).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <sim/scene.hpp>
#include <sim/world.hpp>

#include <tinyline/common/status.hpp>

namespace tinyline::sim {

enum class TrussClass : char { kA = 'A', kB = 'B', kC = 'C' };

/// How the truss settles (see the top of this file).
enum class TrussPhysics : int { kPendulum = 0, kElasticRod = 1 };

/// "pendulum" or "elastic_rod" to the physics; nullopt otherwise.
[[nodiscard]] std::optional<TrussPhysics> parse_truss_physics(std::string_view s);

/// "A", "B" or "C" (case-insensitive) to the class; nullopt otherwise.
[[nodiscard]] std::optional<TrussClass> parse_truss_class(std::string_view s);

struct TrussParams {
  TrussClass complexity = TrussClass::kB;
  int num_tomatoes = 0;  ///< 0: drawn from the class (A 1-2, B 3-4, C 5-8); else 1..8
  std::uint64_t seed = 1;
  std::string name = "truss";           ///< object name prefix
  Eigen::Vector3d origin_m{0, 0, 1.2};  ///< where the peduncle leaves the main stem [m]
  double radius_min_m = 0.025;          ///< tomato radius range (volume-equivalent sphere) [m]
  double radius_max_m = 0.040;
  /// Real fruit are not spheres: polar / equatorial radius drawn in this
  /// range (round tomatoes are slightly oblate) ...
  double flatness_min = 0.82;
  double flatness_max = 0.98;
  double rib_max = 0.03;                ///< ... with up to this relative rib depth (5-6 lobes)
  bool mesh_fruit = true;               ///< false: perfect spheres (flatness and ribs ignored)
  double pedicel_length_min_m = 0.012;  ///< anchor to calyx [m]
  double pedicel_length_max_m = 0.035;
  double pedicel_radius_m = 0.003;  ///< 6 mm pedicels (the thesis's pedicel diameter)
  double peduncle_radius_m = 0.0045;
  double density_kg_m3 = 1000.0;  ///< tomato flesh
  /// Pedicel bending stiffness as a share of the tomato's gravity torque
  /// m g (pedicel + radius) at one radian: drawn per tomato in this range.
  double stiffness_ratio_min = 0.08;
  double stiffness_ratio_max = 0.45;
  double rest_tilt_max_deg = 55.0;  ///< rest direction of a pedicel: up to this from straight down
  /// Leaves: -1 picks from the class (A: none in front; B: 1-2 partly in
  /// front; C: 2-4 in front), else this many in front of the truss.
  int front_leaves = -1;
  bool background_leaves = true;    ///< leaves and a stem behind the truss
  bool distractor_truss = true;     ///< B and C: another truss further back (a second branch)
  bool room = true;                 ///< floor and a back wall
  double camera_distance_m = 0.45;  ///< camera to the truss centre [m]
  double camera_jitter_m = 0.03;    ///< random lateral / vertical offset of the camera [m]
  double camera_yaw_jitter_deg = 10.0;

  TrussPhysics physics = TrussPhysics::kPendulum;
  /// kElasticRod: Young's moduli, drawn per pedicel and per truss. The
  /// pedicels' range puts E I / L over the pendulum world's torsion springs
  /// (0.08-0.45 m g arm per radian); the peduncle's lets a loaded truss sag
  /// by centimetres. Assumptions, not measurements.
  double pedicel_young_min_pa = 2e6;
  double pedicel_young_max_pa = 14e6;
  double peduncle_young_min_pa = 0.4e9;
  double peduncle_young_max_pa = 1.2e9;
  double friction = 0.5;     ///< kElasticRod: Coulomb coefficient between fruit, pedicels and peduncle
  int pedicel_segments = 4;  ///< kElasticRod: rod elements per pedicel

  /// Scene ranges beyond the thesis's trusses (all 0: today's scenes).
  double stem_bend_deg = 0.0;      ///< the main stem bends by this over its length (a bow in x)
  double peduncle_curl_deg = 0.0;  ///< the peduncle turns sideways (yaw) by this over its length
  int pedicel_leaves = 0;          ///< leaves between the camera and that many pedicels
  /// Front leaves sit this many fruit radii off the line of sight to their
  /// fruit, uniform in [min, max]: 1.2-1.9 covers an edge, under 1 the centre.
  double front_leaf_offset_min = 1.2;
  double front_leaf_offset_max = 1.9;

  common::Status validate() const;
};

/// Sets one TrussParams field from text (the evaluation's `key=value`
/// options): physics, pedicel_young_min_pa, pedicel_young_max_pa,
/// peduncle_young_min_pa, peduncle_young_max_pa, friction, pedicel_segments,
/// stem_bend_deg, peduncle_curl_deg, pedicel_leaves, front_leaves,
/// front_leaf_offset_min, front_leaf_offset_max, rest_tilt_max_deg.
/// Returns why not when the key is unknown, the value malformed or the
/// result invalid (the field may then hold the rejected value).
common::Status set_truss_option(TrussParams& p, std::string_view key, std::string_view value);

struct TrussTomato {
  Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();
  double radius_m = 0.0;             ///< radius of the sphere of equal volume [m]
  double equatorial_radius_m = 0.0;  ///< the fruit's shape: oblate spheroid ...
  double polar_radius_m = 0.0;       ///< ... whose axis is the pedicel direction ...
  double rib_amplitude = 0.0;        ///< ... with ribs of this relative depth
  int lobes = 5;
  double rib_phase_rad = 0.0;
  double bounding_radius_m = 0.0;  ///< what contacts see
  double mass_kg = 0.0;
  Eigen::Vector3d anchor_m = Eigen::Vector3d::Zero();  ///< where the pedicel leaves the peduncle
  Eigen::Vector3d calyx_m = Eigen::Vector3d::Zero();   ///< where it enters the fruit
  /// Unit direction from the centre along the pedicel (towards the anchor):
  /// the "pedicel direction" the reasoning estimates.
  Eigen::Vector3d pedicel_dir = Eigen::Vector3d::UnitZ();
  /// Force of the pedicel on the fruit at rest [N] (balances gravity and
  /// contacts, Eq. 4.22). Not parallel to pedicel_dir when the pedicel bends.
  Eigen::Vector3d pedicel_force_n = Eigen::Vector3d::Zero();
  /// The pedicel's axis from the anchor to the calyx (two points when it is
  /// straight, the pendulum world; the settled rod's nodes otherwise).
  std::vector<Eigen::Vector3d> pedicel_path_m;
  /// Its object in the world; a meshed fruit is several objects named
  /// object_name + "_p<k>" (patches), a spherical one exactly object_name.
  std::string object_name;
};

enum class ContactKind : int {
  kFruit = 0,     ///< fruit i touches fruit j (an edge of the graph of Eq. 4.17)
  kPeduncle = 1,  ///< fruit i rests on the peduncle (j = -1)
  kPedicel = 2,   ///< fruit i touches the pedicel of fruit j
};

struct TrussContact {
  int i = -1, j = -1;  ///< tomato indices (j = -1: the peduncle)
  ContactKind kind = ContactKind::kFruit;
  double force_n = 0.0;  ///< normal force magnitude at rest [N]
};

struct RelaxationReport {
  bool converged = false;
  int iterations = 0;
  /// Pendulum: largest net torque / (m g l) left at rest; elastic rod:
  /// largest net force on a rod node / the lightest fruit's weight [1].
  double max_torque_residual = 0.0;
  double max_penetration_m = 0.0;  ///< deepest overlap left at rest [m]
  int restarts = 0;                ///< re-draws of a layout that could not settle
};

struct Truss {
  TrussParams params;
  std::vector<TrussTomato> tomatoes;
  std::vector<TrussContact> contacts;
  RelaxationReport relaxation;
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();  ///< suggested hand-camera pose
  std::vector<Eigen::Vector3d> peduncle_m;                           ///< peduncle polyline
  std::vector<Material> materials;                                   ///< per-tomato colours (added by add_to_world)
};

/// Builds and settles a truss. Throws std::invalid_argument on bad parameters.
[[nodiscard]] Truss make_truss(const TrussParams& params);

/// Adds the truss's materials and objects (fruit, pedicels, sepals,
/// peduncle, main stem, leaves, the second branch, the room) to the world.
/// Returns the tomatoes of the second branch (empty when there is none).
std::vector<TrussTomato> add_to_world(const Truss& truss, World& world);

/// Ground truth as scene.truth entries (flattened vectors), read back by
/// truss_truth_from_scene():
///   truss_tomato_centres_m [3n], truss_tomato_radii_m [n] (volume-equivalent),
///   truss_tomato_shapes_m [3n: equatorial, polar, rib], truss_pedicel_dirs [3n],
///   truss_pedicel_anchors_m [3n], truss_pedicel_forces_n [3n],
///   truss_contacts [4m: i, j, kind (ContactKind), force],
///   truss_camera_pose [7: x y z qx qy qz qw], truss_class [1: 0 A, 1 B, 2 C], truss_seed [1],
///   truss_distractor_centres_m [3k] (the second branch's fruit; may be empty);
/// and when a pedicel is not straight (kElasticRod) its path:
///   truss_pedicel_path_counts [n], truss_pedicel_paths_m [3 * sum of counts]
void write_truth(const Truss& truss, Scene& scene, const std::vector<TrussTomato>& distractors = {});

struct TrussTruth {
  TrussClass complexity = TrussClass::kB;
  std::uint64_t seed = 0;
  std::vector<TrussTomato> tomatoes;  ///< object_name and mass are not stored
  std::vector<TrussContact> contacts;
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3d> distractor_centres_m;
};

/// The truth a truss generator wrote into a scene; throws std::runtime_error
/// naming the missing or malformed entry.
[[nodiscard]] TrussTruth truss_truth_from_scene(const Scene& scene);

/// A settled truss in a world of its own: make_truss() then add_to_world().
struct TrussWorld {
  Truss truss;
  World world;
  std::vector<TrussTomato> distractors;  ///< the second branch's fruit (empty when there is none)
};

/// Builds and settles a truss and puts it in a world: what a scene of one
/// truss and the tomato evaluation's scenarios stand on. Throws
/// std::invalid_argument on bad parameters.
[[nodiscard]] TrussWorld make_truss_world(const TrussParams& params);

/// A scene holding one truss (room, leaves, truth), as the `truss`
/// generator makes it from YAML.
[[nodiscard]] Scene make_truss_scene(const TrussParams& params);

}  // namespace tinyline::sim
