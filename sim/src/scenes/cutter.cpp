// SPDX-License-Identifier: Apache-2.0
// The harvesting scissors closing in a truss (sim/scenes/cutter.hpp).
#include <sim/scenes/cutter.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace tinyline::sim {

namespace {

double segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + t * ab)).norm();
}

// Inside the fruit's surface: the oblate spheroid with ribs that
// add_to_world meshes (axis along the pedicel direction), or its sphere.
bool inside_fruit(const TrussTomato& t, const Eigen::Vector3d& p_world) {
  const Eigen::Vector3d d = p_world - t.centre_m;
  if (d.norm() > t.bounding_radius_m + 1e-9 && d.norm() > t.radius_m) return false;
  const Eigen::Matrix3d R =
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), t.pedicel_dir).toRotationMatrix();
  const Eigen::Vector3d q = R.transpose() * d;  // fruit frame: z towards the calyx
  const double rho = std::hypot(q.x(), q.y());
  const double sin_theta = q.norm() > 0 ? rho / q.norm() : 0.0;
  const double phi = std::atan2(q.y(), q.x());
  const double rr = 1.0 + t.rib_amplitude * sin_theta * sin_theta * std::cos(t.lobes * phi + t.rib_phase_rad);
  const double a = t.equatorial_radius_m * rr, c = t.polar_radius_m;
  if (!(a > 0 && c > 0)) return d.norm() <= t.radius_m;  // a truss without shapes: the sphere
  return (rho / a) * (rho / a) + (q.z() / c) * (q.z() / c) <= 1.0;
}

// What occupies the blade box, sample by sample.
struct InTheBlades {
  std::vector<int> pedicels;  // tomato indices, ascending
  std::string blocker;        // the first fruit, peduncle or stem met
};

std::vector<Eigen::Vector3d> blade_samples(const Eigen::Isometry3d& T_world_throat, const BladeParams& p) {
  auto steps = [&](double half) { return std::max(1, static_cast<int>(std::ceil(2 * half / p.grid_m))); };
  const int nx = steps(0.5 * p.opening_m), ny = steps(0.5 * p.thickness_m), nz = steps(p.reach_m);
  std::vector<Eigen::Vector3d> out;
  out.reserve(static_cast<std::size_t>((nx + 1) * (ny + 1) * (nz + 1)));
  for (int i = 0; i <= nx; ++i)
    for (int j = 0; j <= ny; ++j)
      for (int k = 0; k <= nz; ++k) {
        const Eigen::Vector3d local(p.opening_m * (double(i) / nx - 0.5), p.thickness_m * (double(j) / ny - 0.5),
                                    p.reach_m * (2.0 * k / nz - 1.0));
        out.push_back(T_world_throat * local);
      }
  return out;
}

std::string find_blocker(const Truss& truss, const std::vector<Eigen::Vector3d>& samples) {
  const StemRod stem = main_stem(truss);
  for (const auto& q : samples) {
    for (std::size_t i = 0; i < truss.tomatoes.size(); ++i)
      if (inside_fruit(truss.tomatoes[i], q)) return "fruit " + std::to_string(i);
    for (std::size_t k = 0; k + 1 < truss.peduncle_m.size(); ++k)
      if (segment_distance(q, truss.peduncle_m[k], truss.peduncle_m[k + 1]) <= truss.params.peduncle_radius_m)
        return "peduncle";
    if (segment_distance(q, stem.p0, stem.p1) <= stem.radius_m) return "main stem";
  }
  return {};
}

InTheBlades what_is_in_the_blades(const Truss& truss, const Eigen::Isometry3d& T_world_throat, const BladeParams& p) {
  const std::vector<Eigen::Vector3d> samples = blade_samples(T_world_throat, p);
  InTheBlades in;
  in.blocker = find_blocker(truss, samples);
  for (std::size_t i = 0; i < truss.tomatoes.size(); ++i) {
    const TrussTomato& t = truss.tomatoes[i];
    const bool hit = std::any_of(samples.begin(), samples.end(), [&](const Eigen::Vector3d& q) {
      return segment_distance(q, t.anchor_m, t.calyx_m) <= truss.params.pedicel_radius_m;
    });
    if (hit) in.pedicels.push_back(static_cast<int>(i));
  }
  return in;
}

std::string list_pedicels(const std::vector<int>& ids) {
  std::string s = ids.size() == 1 ? "pedicel " : "pedicels ";
  for (std::size_t k = 0; k < ids.size(); ++k)
    s += (k == 0 ? "" : (k + 1 == ids.size() ? " and " : ", ")) + std::to_string(ids[k]);
  return s;
}

}  // namespace

common::Status BladeParams::validate() const {
  if (!(opening_m > 0 && opening_m < 0.2)) return common::Status::invalid("opening_m must be in (0, 0.2) m");
  if (!(reach_m > 0 && reach_m < 0.2)) return common::Status::invalid("reach_m must be in (0, 0.2) m");
  if (!(thickness_m > 0 && thickness_m < 0.05)) return common::Status::invalid("thickness_m must be in (0, 0.05) m");
  if (!(max_cut_diameter_m >= 0 && max_cut_diameter_m < 0.1))
    return common::Status::invalid("max_cut_diameter_m must be in [0, 0.1) m");
  if (!(grid_m >= 1e-4 && grid_m <= 0.01)) return common::Status::invalid("grid_m must be in [0.0001, 0.01] m");
  return common::Status{};
}

const char* to_string(CutResult r) {
  switch (r) {
    case CutResult::kCutTarget: return "cut_target";
    case CutResult::kCutOtherPedicel: return "cut_other_pedicel";
    case CutResult::kClosedOnNothing: return "closed_on_nothing";
    case CutResult::kJammed: return "jammed";
  }
  return "?";
}

Eigen::Isometry3d throat_from_laser(const Eigen::Isometry3d& T_world_laser, double throat_z_m) {
  return T_world_laser * Eigen::Translation3d(0, 0, throat_z_m);
}

StemRod main_stem(const Truss& truss) {
  // sim_truss_test checks this against the rod add_to_world adds.
  const Eigen::Vector3d& o = truss.params.origin_m;
  return {o + Eigen::Vector3d(0, 0.02, -0.6), o + Eigen::Vector3d(0, 0.02, 0.35), 0.007};
}

CutOutcome close_blades(const Truss& truss, const Eigen::Isometry3d& T_world_throat, const BladeParams& params,
                        int target) {
  CutOutcome out;
  if (const auto v = params.validate(); !v.ok()) {
    out.result = CutResult::kJammed;
    out.object = "invalid blade parameters: " + v.message;
    return out;
  }
  if (!T_world_throat.matrix().allFinite()) {
    out.result = CutResult::kJammed;
    out.object = "invalid throat pose (not finite)";
    return out;
  }
  const InTheBlades in = what_is_in_the_blades(truss, T_world_throat, params);
  const double diameters = 2.0 * truss.params.pedicel_radius_m * static_cast<double>(in.pedicels.size());
  if (!in.blocker.empty() || diameters > params.max_cut_diameter_m) {
    out.result = CutResult::kJammed;
    out.object = !in.blocker.empty() ? in.blocker : list_pedicels(in.pedicels);
    return out;
  }
  if (in.pedicels.empty()) return out;  // closed on nothing
  out.severed = in.pedicels;
  const bool got_target = target < 0 || std::find(in.pedicels.begin(), in.pedicels.end(), target) != in.pedicels.end();
  out.result = got_target ? CutResult::kCutTarget : CutResult::kCutOtherPedicel;
  out.tomato = target >= 0 && got_target ? target : in.pedicels.front();
  return out;
}

void drop_tomato(Truss& truss, int i) {
  TrussTomato& t = truss.tomatoes.at(static_cast<std::size_t>(i));
  if (dropped(truss, i)) return;
  const Eigen::Vector3d down(0, 0, -kFallenDrop_m);
  t.centre_m += down;
  t.calyx_m += down;
  t.anchor_m += down;
}

bool dropped(const Truss& truss, int i) {
  const TrussTomato& t = truss.tomatoes.at(static_cast<std::size_t>(i));
  return t.centre_m.z() < truss.params.origin_m.z() - 0.5 * kFallenDrop_m;
}

int drop_tomato(World& world, const Truss& truss, int i) {
  const TrussTomato& t = truss.tomatoes.at(static_cast<std::size_t>(i));
  const std::string& fruit = t.object_name;
  const std::string idx = std::to_string(i), prefix = truss.params.name + "_";
  const double gone_below = truss.params.origin_m.z() - 0.5 * kFallenDrop_m;
  int moved = 0;
  for (std::size_t o = 0; o < world.size(); ++o) {
    const auto id = static_cast<ObjectId>(o);
    const Object& obj = world.object(id);
    const std::string& n = obj.name;
    const bool mine =
        n == fruit || n.rfind(fruit + "_p", 0) == 0 || n == prefix + "pedicel_" + idx || n == prefix + "calyx_" + idx;
    if (!mine || obj.T_world_object.translation().z() < gone_below) continue;
    Eigen::Isometry3d fallen = obj.T_world_object;
    fallen.translation().z() -= kFallenDrop_m;
    world.set_pose(id, fallen);
    ++moved;
  }
  return moved;
}

}  // namespace tinyline::sim
