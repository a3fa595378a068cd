// SPDX-License-Identifier: Apache-2.0
#include <sim/rail.hpp>

#include <algorithm>
#include <cmath>
#include <ostream>
#include <stdexcept>

namespace tinyline::sim {

CalibrationRail::CalibrationRail(SensorParams sensor, RailParams rail)
    : params_(std::move(sensor)), rail_(std::move(rail)), sensor_(params_) {
  const auto mat = world_.materials().find(rail_.material);
  if (!mat) throw std::invalid_argument("calibration rail: unknown material '" + rail_.material + "'");
  Object target;
  target.name = "target";
  target.shape = PlaneShape{Eigen::Vector2d(rail_.target_width_m, rail_.target_height_m)};
  target.material = *mat;
  target_ = world_.add(std::move(target));
  if (!std::isnan(rail_.background_m)) {
    const auto bg = world_.materials().find(rail_.background_material);
    if (!bg) throw std::invalid_argument("calibration rail: unknown material '" + rail_.background_material + "'");
    Object wall;
    wall.name = "background";
    wall.shape = PlaneShape{};
    wall.material = *bg;
    wall.T_world_object.translation() = Eigen::Vector3d(0, 0, rail_.background_m);
    world_.add(std::move(wall));
  }
  set_target_distance(distance_m_);
}

void CalibrationRail::set_target_distance(double d) {
  if (!(d > 0.0) || !std::isfinite(d)) throw std::invalid_argument("calibration rail: distance must be > 0");
  if (!std::isnan(rail_.background_m) && d >= rail_.background_m)
    throw std::invalid_argument("calibration rail: target must be in front of the background");
  distance_m_ = d;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0, 0, d);
  world_.set_pose(target_, T);
}

void CalibrationRail::set_target_material(const std::string& name) {
  const auto mat = world_.materials().find(name);
  if (!mat) throw std::invalid_argument("calibration rail: unknown material '" + name + "'");
  Object o = world_.object(target_);
  // Objects keep their id; only the material changes.
  World w(world_.materials());
  for (std::size_t i = 0; i < world_.size(); ++i) {
    Object c = world_.object(static_cast<ObjectId>(i));
    if (static_cast<ObjectId>(i) == target_) c.material = *mat;
    w.add(std::move(c));
  }
  world_ = std::move(w);
  rail_.material = name;
}

SensorSet CalibrationRail::measure(double t_s, std::span<const int> pulses, std::uint64_t index,
                                   const MeasureOptions& options) const {
  return sensor_.measure(world_, T_world_sensor_, t_s, pulses, index, {}, options);
}

int CalibrationRail::pulses_for_discharge(double fraction, int pixel, double t_s) const {
  const PulseCharges pc = sensor_.pulse_charges(world_, T_world_sensor_, t_s);
  const auto i = static_cast<std::size_t>(pixel);
  const double per_pulse =
      std::max((pc.qa[i] + pc.ambient[i]) / sensor_.sensitivity_ratio(pixel), pc.qb[i] + pc.ambient[i]);
  const double leak_per_pulse = sensor_.leakage_per_ms(pixel) * 1e3 / params_.emitter.pulse_rate_hz;
  const double target = fraction * params_.pixel.full_scale;
  if (per_pulse + leak_per_pulse <= 0.0) return 990;
  const double p = target / (per_pulse + leak_per_pulse);
  return static_cast<int>(std::clamp(std::round(p / 10.0) * 10.0, 10.0, 990.0));
}

std::vector<CalibrationRow> calibration_rows(const SensorSet& set, const World& world, const std::vector<int>& pixels,
                                             const std::vector<std::string>& extra_columns) {
  std::vector<CalibrationRow> rows;
  for (const auto& r : set.readouts) {
    for (int px : pixels) {
      const auto i = static_cast<std::size_t>(px);
      if (i >= set.truth.size() || std::isnan(set.truth[i].range_m)) continue;
      CalibrationRow row;
      row.t_s = r.t_s;
      row.pixel = px;
      row.pulses = r.pulses;
      row.a = r.a[i];
      row.b = r.b[i];
      row.temperature_c = set.temperature_c;
      row.distance_m = set.truth[i].range_m;
      if (set.truth[i].material != kNoMaterial) row.material = world.materials().get(set.truth[i].material).name;
      for (const auto& c : extra_columns) {
        const auto it = set.covariates.find(c);
        row.extra.push_back(it == set.covariates.end() ? kNaN : it->second);
      }
      rows.push_back(std::move(row));
    }
  }
  return rows;
}

void write_calibration_csv(std::ostream& out, const std::vector<CalibrationRow>& rows, bool with_material,
                           const std::vector<std::string>& extra_columns) {
  out << "t_s,pixel,pulses,a,b,temperature_c,distance_m";
  if (with_material) out << ",material";
  for (const auto& c : extra_columns) out << "," << c;
  out << "\n";
  const auto old = out.precision(9);
  for (const auto& r : rows) {
    out << r.t_s << "," << r.pixel << "," << r.pulses << "," << r.a << "," << r.b << "," << r.temperature_c << ","
        << r.distance_m;
    if (with_material) out << "," << r.material;
    for (double v : r.extra) out << "," << v;
    out << "\n";
  }
  out.precision(old);
}

std::vector<CalibrationRow> run_sweep(const CalibrationRail& rail_template, const RailSweep& sweep,
                                      const std::vector<std::string>& extra_columns) {
  CalibrationRail rail = rail_template;
  std::vector<CalibrationRow> rows;
  double t = sweep.t_start_s;
  std::uint64_t index = sweep.first_index;
  const int centre = sweep.pixels.empty() ? rail.sensor().pixels() / 2 : sweep.pixels.front();
  for (double d : sweep.distances_m) {
    rail.set_target_distance(d);
    std::vector<int> schedule = sweep.schedule;
    if (sweep.discharge_fraction) schedule = {rail.pulses_for_discharge(*sweep.discharge_fraction, centre, t)};
    for (int k = 0; k < sweep.sets_per_distance; ++k) {
      const SensorSet set = rail.measure(t, schedule, index++);
      auto r = calibration_rows(set, rail.world(), sweep.pixels, extra_columns);
      rows.insert(rows.end(), std::make_move_iterator(r.begin()), std::make_move_iterator(r.end()));
      t += std::max(sweep.set_period_s, set.t_end_s - set.t_start_s);
    }
  }
  return rows;
}

}  // namespace tinyline::sim
