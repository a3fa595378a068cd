// SPDX-License-Identifier: Apache-2.0
#include "scenes.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace tinyline::laser_clustering::eval {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

using Rng = sim::SceneRng;

sim::MaterialId material(const sim::World& w, const std::string& name) { return sim::material(w, name, "eval scene"); }
using sim::pose;
using sim::rot;

// The target pedicel crosses the world's y = 0 plane here: at the throat, or
// off it by the random offset.
Eigen::Vector3d target_crossing(TrussCase c, Rng& rng, const TrussOptions& o) {
  Eigen::Vector3d cross(0.0, 0.0, o.throat_z_m);
  if (c == TrussCase::kRandomOffset) {
    const double rho = o.max_offset_m * std::sqrt(rng.uniform(0.0, 1.0)),
                 phi = rng.uniform(0.0, 2.0 * std::numbers::pi);
    cross += Eigen::Vector3d(rho * std::cos(phi), 0.0, rho * std::sin(phi));
  }
  return cross;
}

// Where the gripper really is: kRecognitionError moves and turns it, and the
// expectation comes from the vision's (nearly right) tomato.
void place_gripper(TrussCase c, Rng& rng, const Eigen::Vector3d& cross, const sim::HangingTomato& target,
                   const TrussOptions& o, TrussScene& s) {
  if (c != TrussCase::kRecognitionError) {
    s.truth.expected_xz_m = Eigen::Vector2d(0.0, o.throat_z_m);
    return;
  }
  const double rho = rng.uniform(o.recognition_offset_m), phi = rng.uniform(0.0, 2.0 * std::numbers::pi);
  const Eigen::Vector3d estimate = cross + Eigen::Vector3d(rho * std::cos(phi), 0.0, rho * std::sin(phi));
  const Eigen::Matrix3d yaw =
      rot(Eigen::Vector3d::UnitY(), rng.uniform(-o.recognition_yaw_deg, o.recognition_yaw_deg) * kDeg);
  s.T_world_sensor = pose(estimate - yaw * Eigen::Vector3d(0.0, 0.0, o.throat_z_m), yaw);
  // The vision's tomato is right (within a few mm): the pedicel is expected
  // right above its centre.
  const Eigen::Vector3d tomato = target.tomato_centre + Eigen::Vector3d(rng.normal(o.tomato_estimate_sd_m), 0.0,
                                                                        rng.normal(o.tomato_estimate_sd_m));
  const Eigen::Vector3d expected = s.T_world_sensor.inverse() * Eigen::Vector3d(tomato.x(), 0.0, tomato.z());
  s.truth.expected_xz_m = Eigen::Vector2d(expected.x(), expected.z());
  s.truth.expected_sd_m = 0.015;
  s.truth.use_expectation = true;
}

// The vision's view of the whole truss: every tomato within a few mm, each
// pedicel expected right above its tomato (as for the recognition-error
// target). Its own streams, so the scene and the gripper stay as they were.
void expect_as_the_vision(TrussCase c, std::uint64_t seed, const std::vector<sim::HangingTomato>& hangings,
                          const TrussOptions& o, TrussScene& s) {
  Rng vision(seed ^ 0x9e3779b97f4a7c15ULL);
  std::vector<Eigen::Vector3d> estimate;
  std::vector<double> top_y;  // the tomato's top, below the laser plane (y = 0) when positive
  for (const auto& h : hangings) {
    const Eigen::Vector3d noise(vision.normal(o.tomato_estimate_sd_m), vision.normal(o.tomato_estimate_sd_m),
                                vision.normal(o.tomato_estimate_sd_m));
    estimate.push_back(h.tomato_centre + noise);
    top_y.push_back(estimate.back().y() - h.tomato_radius);
    estimate.back().y() = 0.0;
  }
  const Eigen::Isometry3d T_sensor_world = s.T_world_sensor.inverse();
  Rng radius_noise(seed ^ 0x5851f42d4c957f2dULL);
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    const Eigen::Vector3d centre(estimate[i].x(), top_y[i] + hangings[i].tomato_radius, estimate[i].z());
    const Eigen::Vector3d e = c == TrussCase::kRandomOffset
                                  ? Eigen::Vector3d(0.0, 0.0, o.throat_z_m) +
                                        (centre - Eigen::Vector3d(estimate[0].x(), 0.0, estimate[0].z()))
                                  : Eigen::Vector3d(T_sensor_world * centre);
    s.truth.tomatoes_expected.push_back(
        {e, std::max(0.005, hangings[i].tomato_radius + radius_noise.normal(o.tomato_radius_sd_m))});
  }
  for (std::size_t i = 1; i < estimate.size(); ++i) {
    // A tomato whose top reaches the plane puts itself, not its pedicel, in the scan.
    if (top_y[i] < -o.expected_tomato_in_plane_m) continue;
    Eigen::Vector3d e;
    if (c == TrussCase::kRandomOffset) {
      // The offset moved the whole recognition result: the target's
      // expectation is the throat, the layout around it is the vision's.
      e = Eigen::Vector3d(0.0, 0.0, o.throat_z_m) + (estimate[i] - estimate[0]);
    } else {
      e = T_sensor_world * estimate[i];
    }
    s.truth.neighbours_expected.push_back({Eigen::Vector2d(e.x(), e.z()), top_y[i] < o.expected_pedicel_clearance_m});
  }
}

}  // namespace

std::string set_truss_option(TrussOptions& o, const std::string& key, const std::string& value) {
  double x = 0.0;
  std::size_t used = 0;
  try {
    x = std::stod(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != value.size() || !std::isfinite(x))
    return "scene option '" + key + "' wants a number, got '" + value + "'";
  if (key == "max_tilt_deg") {
    if (x < 0 || x > 60) return "max_tilt_deg must be in [0, 60]";
    o.max_tilt_deg = x;
  } else if (key == "stem_bow_m") {
    if (std::abs(x) > 0.1) return "stem_bow_m must be in [-0.1, 0.1]";
    o.stem_bow_m = x;
  } else {
    return "unknown scene option '" + key + "' (max_tilt_deg, stem_bow_m)";
  }
  return {};
}

TrussScene make_truss_scene(TrussCase c, std::uint64_t seed, const TrussOptions& o) {
  Rng rng(seed);
  TrussScene s;
  const Eigen::Vector3d cross = target_crossing(c, rng, o);
  const sim::CloseTruss truss = sim::add_close_truss(s.world, rng, seed, cross, o.throat_z_m, o);
  for (const auto& h : truss.hangings) {
    s.truth.pedicels.push_back(h.pedicel);
    s.truth.tomatoes.push_back(h.tomato);
  }
  s.truth.target_pedicel = s.truth.pedicels.front();
  s.truth.target_radius_m = truss.hangings.front().radius;
  s.truth.stem = truss.stem;
  place_gripper(c, rng, cross, truss.hangings.front(), o, s);
  expect_as_the_vision(c, seed, truss.hangings, o, s);
  s.truth.target_in_sensor = s.T_world_sensor.inverse() * cross;
  return s;
}

StickScene make_stick_scene(std::uint64_t seed, const StickOptions& o) {
  Rng rng(seed);
  StickScene s;
  sim::World& w = s.world;
  const double d = rng.uniform(o.panel_distance_m);
  auto tilt = [&]() -> Eigen::Matrix3d {
    return rot(Eigen::Vector3d::UnitY(), rng.uniform(-o.max_tilt_deg, o.max_tilt_deg) * kDeg) *
           rot(Eigen::Vector3d::UnitX(), rng.uniform(-o.max_tilt_deg, o.max_tilt_deg) * kDeg);
  };
  s.panel = w.add({"panel", sim::PlaneShape{Eigen::Vector2d(0.6, 0.6)}, pose(Eigen::Vector3d(0, 0, d), tilt()),
                   material(w, o.panel_material)});
  // The stick stands off the panel: its front face front_gap before it, its
  // back no deeper than the panel.
  const double thickness = std::min(o.stick_thickness_m, o.front_gap_m);
  const double x = rng.uniform(-o.lateral_m, o.lateral_m);
  // The panel's depth at the stick (the panel is tilted).
  const auto& T_panel = w.object(s.panel).T_world_object;
  const Eigen::Vector3d n = T_panel.linear().col(2);
  const double panel_z = d - n.x() * x / n.z();
  s.stick = w.add({"stick", sim::BoxShape{Eigen::Vector3d(o.stick_width_m, 0.3, thickness)},
                   pose(Eigen::Vector3d(x, 0.0, panel_z - o.front_gap_m + thickness / 2), tilt()),
                   material(w, o.stick_material)});
  return s;
}

Eigen::Isometry3d WrenchScene::T_world_sensor(double pitch_rad) const {
  // Rotate about the laser's x axis around a pivot behind it.
  return pose(Eigen::Vector3d(0.0, 0.0, -pivot_behind_m)) *
         pose(Eigen::Vector3d::Zero(), rot(Eigen::Vector3d::UnitX(), pitch_rad)) *
         pose(Eigen::Vector3d(0.0, 0.0, pivot_behind_m));
}

WrenchScene make_wrench_scene(std::uint64_t seed, const WrenchOptions& o) {
  Rng rng(seed);
  WrenchScene s;
  s.pivot_behind_m = o.pivot_behind_m;
  sim::World& w = s.world;
  const double d = rng.uniform(o.panel_distance_m);
  w.add({"panel", sim::PlaneShape{Eigen::Vector2d(0.8, 0.8)}, pose(Eigen::Vector3d(0, 0, d)),
         material(w, o.panel_material)});
  const double pitch = rng.uniform(-o.max_face_pitch_deg, o.max_face_pitch_deg) * kDeg;
  const double yaw = rng.uniform(-o.max_face_yaw_deg, o.max_face_yaw_deg) * kDeg;
  const Eigen::Matrix3d R = rot(Eigen::Vector3d::UnitY(), yaw) * rot(Eigen::Vector3d::UnitX(), pitch);
  const Eigen::Vector3d size(o.wrench_size_m[0], o.wrench_size_m[1], o.wrench_size_m[2]);
  // Hanging on the panel: pulled forward so no corner goes through it.
  const double reach =
      0.5 * (std::abs(R(2, 0)) * size.x() + std::abs(R(2, 1)) * size.y() + std::abs(R(2, 2)) * size.z());
  s.wrench = w.add({"wrench", sim::BoxShape{size},
                    pose(Eigen::Vector3d(rng.uniform(-o.lateral_m, o.lateral_m), 0.0, d - reach - 0.001), R),
                    material(w, o.wrench_material)});
  // The face towards the laser has normal -R z; square means the optical axis
  // R_x(p) z runs along m = R z in the y-z plane: (0, -sin p, cos p) ~ (m_y, m_z).
  const Eigen::Vector3d m = R.col(2);
  s.true_pitch_rad = std::atan2(-m.y(), m.z());
  return s;
}

}  // namespace tinyline::laser_clustering::eval
