// SPDX-License-Identifier: Apache-2.0
// The multi-sensor sequence mode (thesis 6.2.1, Algorithm 4), scheduled
// better. The sensors accumulate incident 905 nm light, so a sensor whose
// gates are open while another's laser lights a surface it sees is
// corrupted. The thesis switches the n lasers on one at a time, dividing
// every sensor's rate by n. Here:
//
//  1. interference_graph: in the sensing plane, sensor j's fan is cast as
//     rays against the known occluders (the object's current estimate, the
//     robot's links); each lit point that sensor i sees (inside its field of
//     view and range, line of sight free) makes i and j conflict. A ray that
//     hits nothing known lights its whole length up to the range (something
//     unknown may stand anywhere on it), which keeps the graph conservative.
//  2. colour_graph: a minimum colouring (exact branch and bound for the
//     sizes of a robot, DSatur beyond).
//  3. colouring_schedule: one slot per colour class; then every sensor is
//     added to every other slot none of whose sensors it conflicts with, so
//     a sensor that conflicts with nobody runs every slot.
//  4. Sequencer: recomputes all of it when the joints (sensor poses) or the
//     object estimate move more than a threshold.
// Core code: geometry and graphs only, no timing source and no I/O.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hydrus_fitting/circle_fit.hpp"
#include "hydrus_fitting/robot_model.hpp"

namespace tinyline::hydrus_fitting {

/// One sensor in the sensing plane (base frame).
struct SensorView2D {
  Eigen::Vector2d origin_m = Eigen::Vector2d::Zero();
  double yaw_rad = 0.0;              ///< optical axis (and fan centre)
  double fov_half_angle_rad = 0.6;   ///< receiver, along the line
  double fan_half_angle_rad = 0.66;  ///< emitter
  double range_m = 2.0;              ///< light beyond this is ignored (both ways)
};

/// The sensors of a robot model at one configuration.
[[nodiscard]] std::vector<SensorView2D> sensor_views(const RobotModel& model, const Kinematics& k);

/// A thick segment (a robot link): points within half_width_m of a-b.
struct Capsule {
  Eigen::Vector2d a_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d b_m = Eigen::Vector2d::Zero();
  double half_width_m = 0.0;
};

/// 2-D ray casts, the ray o + t d with d a unit vector: the distance t > 1e-9
/// to the first crossing, or infinity. Shared by the interference check and
/// the evaluation's planar scenes.
[[nodiscard]] double ray_circle(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const Eigen::Vector2d& c, double r);
[[nodiscard]] double ray_segment(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const Eigen::Vector2d& p,
                                 const Eigen::Vector2d& q);
/// First hit with a capsule's two end caps and two sides.
[[nodiscard]] double ray_capsule(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const Capsule& c);
[[nodiscard]] bool inside_capsule(const Eigen::Vector2d& p, const Capsule& c);

/// What blocks light in the plane.
struct Occluders {
  std::vector<Circle> circles;    ///< objects (e.g. the fitted cylinder)
  std::vector<Capsule> capsules;  ///< robot links
};

/// The robot's links as capsules at one configuration.
[[nodiscard]] std::vector<Capsule> link_capsules(const RobotModel& model, const Kinematics& k);

struct InterferenceParams {
  int rays_per_fan = 64;  ///< rays cast across each emitter's fan
  double step_m = 0.02;   ///< sampling along rays that hit nothing
  /// Widens every field of view and fan [rad]: the sensors move between
  /// recomputations, and fans have soft edges.
  double angle_margin_rad = 0.05;
  /// Circles are shrunk by this before occluding [m] (an estimate's error
  /// must not hide a conflict).
  double occluder_shrink_m = 0.01;
};

/// Conflicts between sensors: symmetric, no self edges.
struct InterferenceGraph {
  int n = 0;
  std::vector<std::uint8_t> adjacency;     ///< n x n, row-major
  std::vector<Eigen::Vector2d> witness_m;  ///< n x n: a point lit by column j seen by row i (NaN if none)
  [[nodiscard]] bool conflict(int i, int j) const { return adjacency[static_cast<std::size_t>(i * n + j)] != 0; }
  [[nodiscard]] int edges() const;
};

[[nodiscard]] InterferenceGraph interference_graph(std::span<const SensorView2D> sensors, const Occluders& occluders,
                                                   const InterferenceParams& params = {});
/// A graph from an explicit edge list (tests, fixed installations).
[[nodiscard]] InterferenceGraph graph_from_edges(int n, std::span<const std::pair<int, int>> edges);

struct Colouring {
  std::vector<int> colour;  ///< per sensor, 0 .. colours-1
  int colours = 0;
  bool optimal = false;  ///< proven minimum (exact search finished)
};

/// Minimum colouring: exact branch and bound up to `exact_limit` vertices,
/// DSatur (greedy, usually optimal on small graphs) beyond.
[[nodiscard]] Colouring colour_graph(const InterferenceGraph& g, int exact_limit = 24);

/// Slot timing of the sequence mode: a slot holds one measurement set of the
/// sensors on in it plus the guard for the on/off commands to take effect.
struct SlotTiming {
  double set_period_s = 1.0 / 60.0;  ///< one set at the sensor's free-running rate (60-100 Hz at short range)
  double guard_s = 0.002;            ///< command latency margin between slots
  [[nodiscard]] double slot_s() const { return set_period_s + guard_s; }
};

struct Schedule {
  std::string name;                     ///< "time_slicing" (thesis) or "colouring"
  std::vector<std::vector<int>> slots;  ///< sensors emitting in each slot, ascending
  std::vector<double> rate_hz;          ///< sets per second per sensor
  SlotTiming timing;
  [[nodiscard]] int slot_count() const { return static_cast<int>(slots.size()); }
  [[nodiscard]] double cycle_s() const { return timing.slot_s() * static_cast<double>(slots.size()); }
  [[nodiscard]] bool emits(int slot, int sensor) const;
  [[nodiscard]] double min_rate_hz() const;
};

/// The thesis's sequence mode: n slots, one sensor each (rate / n).
[[nodiscard]] Schedule time_slicing_schedule(int n, const SlotTiming& timing = {});
/// One slot per colour class; `fill` adds each sensor to every other slot it
/// conflicts with nobody in.
[[nodiscard]] Schedule colouring_schedule(const InterferenceGraph& g, const Colouring& c, const SlotTiming& timing = {},
                                          bool fill = true);
/// The schedule for sensors some of which emit whatever they are told (a
/// firmware that ignores the laser command): those emit in every slot, and a
/// slot that only held such sensors is dropped (it gave nobody else time).
[[nodiscard]] Schedule with_always_emitting(Schedule s, std::span<const int> always);
/// Why a schedule is unsafe for a graph (two conflicting sensors share a
/// slot, a sensor never emits): InvalidArgument, ok when it is safe.
[[nodiscard]] common::Status check_schedule(const InterferenceGraph& g, const Schedule& s);

struct SequencerParams {
  InterferenceParams interference;
  SlotTiming timing;
  bool fill = true;
  /// Rebuild the graph when a sensor moved this far since the last build...
  double recompute_translation_m = 0.02;
  double recompute_rotation_rad = 0.035;
  /// ...or the object estimate moved (centre or radius) this far [m].
  double recompute_object_m = 0.02;
  bool links_occlude = true;  ///< the robot's links block light
};

/// Keeps the schedule of a moving robot up to date.
class Sequencer {
 public:
  explicit Sequencer(const RobotModel& model, SequencerParams params = {});

  /// Recomputes when needed; returns true when the schedule changed.
  /// `object`: the current estimate of the object (occludes), if any.
  bool update(std::span<const double> joint_positions, const std::optional<Circle>& object);

  [[nodiscard]] const Schedule& schedule() const { return schedule_; }
  [[nodiscard]] const InterferenceGraph& graph() const { return graph_; }
  [[nodiscard]] const Colouring& colouring() const { return colouring_; }
  [[nodiscard]] int rebuilds() const { return rebuilds_; }
  [[nodiscard]] const SequencerParams& params() const { return params_; }

 private:
  const RobotModel* model_;
  SequencerParams params_;
  std::vector<SensorView2D> last_views_;
  std::optional<Circle> last_object_;
  bool built_ = false;
  InterferenceGraph graph_;
  Colouring colouring_;
  Schedule schedule_;
  int rebuilds_ = 0;
};

}  // namespace tinyline::hydrus_fitting
