// SPDX-License-Identifier: Apache-2.0
// The verification's and the harvest's shared steps on a scenario (internal
// to the evaluation library).
#pragma once

#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include <sim/world.hpp>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/eval/verification.hpp"
#include "tomato_reasoning/pick_pose.hpp"
#include "tomato_reasoning/pipeline.hpp"

namespace tinyline::tomato_reasoning::eval {

/// Each true pedicel (anchor -> calyx) in the scenario's reference frame, in the truss's order.
[[nodiscard]] std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> true_pedicels(const Scenario& s);

/// The blade throat at `T_ref_laser` holds `pedicel`: it crosses the laser
/// plane within half the opening of the throat across it and within the
/// depth tolerance along the blades. `lateral`, `depth` (optional) get where.
[[nodiscard]] bool throat_on_pedicel(const VerificationOptions& o,
                                     const std::pair<Eigen::Vector3d, Eigen::Vector3d>& pedicel,
                                     const Eigen::Isometry3d& T_ref_laser, double* lateral, double* depth);

/// Fruit `truth` (with its pedicel and sepals) leaves `world`: picked, or finished by hand.
void remove_fruit(const Scenario& s, sim::World& world, int truth);

/// The true tomato a detection's centre lies within `match_m` of; -1 when none.
[[nodiscard]] int matched_truth(const Scenario& s, const Tomato& det, double match_m);

/// The picking pose's parameters with the approach from the camera's side.
[[nodiscard]] PickPoseParams camera_side(PickPoseParams p);

}  // namespace tinyline::tomato_reasoning::eval
