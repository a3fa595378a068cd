// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/pick_pose.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace tinyline::tomato_reasoning {

PickPose picking_pose(const Eigen::Vector3d& cut_point, const Eigen::Vector3d& pedicel_axis, const PickPoseParams& p) {
  PickPose pose;
  if (!cut_point.allFinite() || !pedicel_axis.allFinite() || !(pedicel_axis.norm() > 1e-9)) {
    pose.reason = "cut point or pedicel direction not finite";
    return pose;
  }
  const Eigen::Vector3d y = pedicel_axis.normalized();  // the line cuts across the pedicel
  // Look from the robot's side, square to the pedicel.
  Eigen::Vector3d z = cut_point - p.approach_from;
  z -= z.dot(y) * y;
  if (z.norm() < 1e-6) z = y.unitOrthogonal();  // approaching along the pedicel: any square direction
  z.normalize();
  const Eigen::Vector3d x = y.cross(z);
  pose.T_ref_laser.linear().col(0) = x;
  pose.T_ref_laser.linear().col(1) = y;
  pose.T_ref_laser.linear().col(2) = z;
  pose.T_ref_laser.translation() = cut_point - p.throat_z_m * z;  // the throat on the cut point
  pose.cut_point = cut_point;
  pose.pedicel_axis = y;
  pose.tomato = 0;
  return pose;
}

namespace {

// How far the laser's rays to the throat (and a blade opening either side)
// pass from the fruit that cut the scan plane [m]; negative: blocked.
double view_clearance(const Eigen::Isometry3d& T_ref_laser, const std::vector<Sphere>& fruit, const PickPoseParams& p) {
  const Eigen::Isometry3d T = T_ref_laser.inverse();
  double worst = std::numeric_limits<double>::infinity();
  for (const Sphere& o : fruit) {
    const Eigen::Vector3d c = T * o.centre;
    const double r2 = o.radius_m * o.radius_m - c.y() * c.y();
    if (!(r2 > 0)) continue;  // off the plane (or not finite)
    const Eigen::Vector2d q(c.x(), c.z());
    for (double dx : {-0.02, 0.0, 0.02}) {
      const Eigen::Vector2d end(dx, p.throat_z_m);
      const double s = std::clamp(q.dot(end) / end.squaredNorm(), 0.0, 1.0);
      worst = std::min(worst, (q - s * end).norm() - std::sqrt(r2));
    }
  }
  return worst;
}

constexpr double kOwnFruitMargin_m = 0.001;

// Turns from the straight approach, smallest first: 0, +step, -step, ...
std::vector<double> rolls_deg(const PickPoseParams& p) {
  std::vector<double> out{0.0};
  if (!(p.roll_step_deg > 0)) return out;
  for (double step = p.roll_step_deg; step <= p.max_turn_deg + 1e-9; step += p.roll_step_deg) {
    out.push_back(step);
    out.push_back(-step);
  }
  return out;
}

// Candidate order: fits the blades, clears the view, smaller roll, preferred offset.
bool better(const CutCandidate& a, const CutCandidate& b, const PickPoseParams& p) {
  if (a.fits(p) != b.fits(p)) return a.fits(p);
  if (!a.fits(p)) return a.blade_clear_m > b.blade_clear_m;
  const bool av = a.view_clear_m >= p.view_clearance_m, bv = b.view_clear_m >= p.view_clearance_m;
  if (av != bv) return av;
  return false;  // otherwise keep the generation order (roll, then offset)
}

}  // namespace

PickPose rolled(const PickPose& pose, double roll_rad, double throat_z_m) {
  PickPose turned = pose;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(roll_rad, pose.pedicel_axis).toRotationMatrix();
  turned.T_ref_laser.linear() = R * pose.T_ref_laser.linear();
  turned.T_ref_laser.translation() = pose.cut_point - throat_z_m * turned.T_ref_laser.linear().col(2);
  return turned;
}

double blade_clearance(const Eigen::Isometry3d& T_ref_laser, const Sphere& s, const PickPoseParams& p) {
  const Eigen::Vector3d c = T_ref_laser.inverse() * s.centre - Eigen::Vector3d(0, 0, p.throat_z_m);
  const Eigen::Vector3d half(0.5 * p.blades.opening_m, 0.5 * p.blades.thickness_m, p.blades.reach_m);
  const Eigen::Vector3d outside = (c.cwiseAbs() - half).cwiseMax(0.0);
  return outside.norm() - s.radius_m;
}

std::vector<CutCandidate> cut_candidates(const Sphere& target, const Eigen::Vector3d& pedicel_dir,
                                         const std::vector<Sphere>& others, const PickPoseParams& p) {
  std::vector<CutCandidate> out;
  if (!pedicel_dir.allFinite() || !(pedicel_dir.norm() > 1e-9)) return out;
  const Eigen::Vector3d u = pedicel_dir.normalized();
  for (double roll : rolls_deg(p)) {
    for (double offset : p.cut_offsets_m) {
      const PickPose straight = picking_pose(target.centre + (target.radius_m + offset) * u, u, p);
      if (!straight.ok()) return out;
      CutCandidate c;
      c.pose = rolled(straight, roll * M_PI / 180.0, p.throat_z_m);
      c.offset_m = offset;
      c.roll_rad = roll * M_PI / 180.0;
      // The target's own surface stands where its sphere says relative to
      // the blades (both follow the same pedicel): 1 mm is margin enough.
      c.blade_clear_m = blade_clearance(c.pose.T_ref_laser, target, p) + p.blades.margin_m - kOwnFruitMargin_m;
      for (const Sphere& f : others)
        c.blade_clear_m = std::min(c.blade_clear_m, blade_clearance(c.pose.T_ref_laser, f, p));
      c.view_clear_m = view_clearance(c.pose.T_ref_laser, others, p);
      out.push_back(c);
    }
  }
  std::stable_sort(out.begin(), out.end(),
                   [&](const CutCandidate& a, const CutCandidate& b) { return better(a, b, p); });
  return out;
}

std::vector<CutCandidate> cut_candidates(const PipelineResult& r, int index, const std::vector<int>& gone,
                                         const PickPoseParams& p) {
  if (index < 0 || static_cast<std::size_t>(index) >= r.tomatoes.size()) return {};
  std::vector<Sphere> others;
  for (std::size_t k = 0; k < r.tomatoes.size(); ++k)
    if (static_cast<int>(k) != index && std::find(gone.begin(), gone.end(), static_cast<int>(k)) == gone.end())
      others.push_back(r.tomatoes[k].fit.sphere);
  const Tomato& t = r.tomatoes[static_cast<std::size_t>(index)];
  std::vector<CutCandidate> out = cut_candidates(t.fit.sphere, t.cut.direction, others, p);
  for (CutCandidate& c : out) c.pose.tomato = index;
  return out;
}

PickPose picking_pose(const Eigen::Vector3d& cut_point, const Eigen::Vector3d& pedicel_axis,
                      const std::vector<Sphere>& fruit, const PickPoseParams& p) {
  const PickPose pose = picking_pose(cut_point, pedicel_axis, p);
  if (!pose.ok() || !(p.max_turn_deg > 0)) return pose;
  PickPose best = pose;
  double best_clear = view_clearance(pose.T_ref_laser, fruit, p);
  if (best_clear >= p.view_clearance_m) return pose;
  // The smallest turn that clears the view, else the clearest.
  for (double step = 15.0; step <= p.max_turn_deg + 1e-9; step += 15.0) {
    for (double sign : {1.0, -1.0}) {
      const PickPose turned = rolled(pose, sign * step * M_PI / 180.0, p.throat_z_m);
      const double c = view_clearance(turned.T_ref_laser, fruit, p);
      if (c >= p.view_clearance_m) return turned;
      if (c > best_clear) best = turned, best_clear = c;
    }
  }
  return best;
}

PickPose picking_pose(const PipelineResult& r, int index, const PickPoseParams& p) {
  if (index < 0 || static_cast<std::size_t>(index) >= r.tomatoes.size()) {
    PickPose pose;
    pose.reason = "tomato " + std::to_string(index) + " of " + std::to_string(r.tomatoes.size());
    return pose;
  }
  std::vector<Sphere> fruit;
  for (const Tomato& t : r.tomatoes) fruit.push_back(t.fit.sphere);
  const Tomato& t = r.tomatoes[static_cast<std::size_t>(index)];
  PickPose pose = picking_pose(t.cut.point, t.cut.direction, fruit, p);
  if (pose.ok()) pose.tomato = index;
  return pose;
}

std::vector<PickPose> nearby_cuts(const PickPose& at, const Sphere& own, const std::vector<Sphere>& others,
                                  const PickPoseParams& p, const CutProbeParams& probe) {
  struct Ranked {
    PickPose pose;
    double cost;
  };
  std::vector<Ranked> found;
  if (!at.ok()) return {};
  const Eigen::Vector3d axis = at.pedicel_axis.normalized();
  for (double shift : probe.shifts_m) {
    PickPose moved = at;
    moved.cut_point += shift * axis;
    moved.T_ref_laser.translation() += shift * axis;
    for (double roll : probe.rolls_deg) {
      if (shift == 0.0 && roll == 0.0) continue;  // that is `at`
      const PickPose pose = rolled(moved, roll * M_PI / 180.0, p.throat_z_m);
      if (blade_clearance(pose.T_ref_laser, own, p) < kOwnFruitMargin_m) continue;
      const bool clear = std::all_of(others.begin(), others.end(), [&](const Sphere& f) {
        return blade_clearance(pose.T_ref_laser, f, p) >= p.blades.margin_m;
      });
      if (!clear) continue;
      found.push_back({pose, std::abs(shift) / probe.shift_scale_m + std::abs(roll) / probe.roll_scale_deg});
    }
  }
  std::stable_sort(found.begin(), found.end(), [](const Ranked& a, const Ranked& b) { return a.cost < b.cost; });
  std::vector<PickPose> out;
  for (const Ranked& r : found) out.push_back(r.pose);
  return out;
}

const char* to_string(Verification::Outcome o) {
  switch (o) {
    case Verification::Outcome::kCutHere: return "cut_here";
    case Verification::Outcome::kMove: return "move";
    case Verification::Outcome::kNothingFound: return "nothing_found";
    case Verification::Outcome::kOutOfView: return "out_of_view";
    case Verification::Outcome::kFailed: return "failed";
  }
  return "?";
}

Verification verify(const PickPose& pose, const FinderAnswer& a, const PickPoseParams& p) {
  Verification v;
  v.confidence = a.confidence;
  v.reason = a.reason;
  v.T_ref_laser_final = pose.T_ref_laser;
  v.cut_point = pose.cut_point;
  if (!pose.ok()) {
    v.reason = "no picking pose: " + pose.reason;
    return v;
  }
  using O = FinderAnswer::Outcome;
  switch (a.outcome) {
    case O::kCutHere:
    case O::kMove: {
      if (!std::isfinite(a.lateral_offset_m) || !std::isfinite(a.depth_offset_m)) {
        v.reason = "pedicel finder gave a non-finite move";
        return v;
      }
      const Eigen::Matrix3d R = pose.T_ref_laser.linear();
      v.move = R * Eigen::Vector3d(a.lateral_offset_m, 0.0, a.depth_offset_m);
      if (v.move.norm() > p.max_move_m) {
        v.outcome = Verification::Outcome::kNothingFound;
        v.reason = "the finder's pedicel is " + std::to_string(std::lround(1000 * v.move.norm())) +
                   " mm from the plan, beyond max_move_m: another pedicel or a stem (" + a.reason + ")";
        v.move.setZero();
        return v;
      }
      v.T_ref_laser_final.translation() += v.move;
      v.cut_point = v.T_ref_laser_final * Eigen::Vector3d(0, 0, p.throat_z_m);
      v.outcome = a.outcome == O::kCutHere ? Verification::Outcome::kCutHere : Verification::Outcome::kMove;
      return v;
    }
    case O::kNothingToCut: v.outcome = Verification::Outcome::kNothingFound; return v;
    case O::kOutOfView: v.outcome = Verification::Outcome::kOutOfView; return v;
    case O::kInvalidInput: v.outcome = Verification::Outcome::kFailed; return v;
  }
  return v;
}

}  // namespace tinyline::tomato_reasoning
