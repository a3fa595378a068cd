// SPDX-License-Identifier: Apache-2.0
// The calibration rail (thesis 3.3.3, 3.5): a flat target of one material,
// square to the sensor's optical axis, moved to chosen distances; and the
// calibration data set the calibration tool reads, one row per pixel
// read-out: t_s,pixel,pulses,a,b,temperature_c,distance_m[,material][,covariates...]
#pragma once

#include <cstdint>
#include <iosfwd>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <sim/tof_sensor.hpp>

namespace tinyline::sim {

struct RailParams {
  std::string material = "white_paper";
  double target_width_m = 1.0;  ///< along the sensor's line (x)
  double target_height_m = 0.5;
  /// A wall behind the target at this distance from the sensor (NaN: none,
  /// the rays that miss the target see nothing).
  double background_m = kNaN;
  std::string background_material = "wall_paint";
};

/// A sensor in front of a movable target. The sensor sits at the world origin
/// looking along +z; the target's surface is at z = distance.
class CalibrationRail {
 public:
  explicit CalibrationRail(SensorParams sensor, RailParams rail = {});

  void set_target_distance(double distance_m);
  [[nodiscard]] double target_distance() const { return distance_m_; }
  /// Swaps the target's material (Table 3.2 runs).
  void set_target_material(const std::string& name);

  [[nodiscard]] const World& world() const { return world_; }
  [[nodiscard]] const TofLineSensor& sensor() const { return sensor_; }
  [[nodiscard]] const Eigen::Isometry3d& T_world_sensor() const { return T_world_sensor_; }

  /// One set at sensor time t_s with the given read-out schedule.
  [[nodiscard]] SensorSet measure(double t_s, std::span<const int> pulses, std::uint64_t index,
                                  const MeasureOptions& options = {}) const;
  /// Pulse count (multiple of 10 in [10, 990]) that discharges the fuller
  /// capacitor of `pixel` to about `fraction` of full scale at the current
  /// distance: the thesis's fixed-discharge calibration data (3.5: 40 %, 20 %).
  [[nodiscard]] int pulses_for_discharge(double fraction, int pixel, double t_s) const;

 private:
  SensorParams params_;
  RailParams rail_;
  World world_;
  TofLineSensor sensor_;
  ObjectId target_ = kNoObject;
  double distance_m_ = 0.3;
  Eigen::Isometry3d T_world_sensor_ = Eigen::Isometry3d::Identity();
};

/// One row of the calibration CSV.
struct CalibrationRow {
  double t_s = 0.0;
  int pixel = 0;
  int pulses = 0;
  double a = 0.0;  ///< [charge_unit]
  double b = 0.0;  ///< [charge_unit]
  double temperature_c = 0.0;
  double distance_m = kNaN;  ///< true range along the pixel's ray
  std::string material;
  std::vector<double> extra;  ///< values of the extra columns, in column order
};

/// Rows of every read-out of the chosen pixels of a set (non-dark pixels with
/// a true range). Covariates of the set become extra columns, in `extra_columns` order.
[[nodiscard]] std::vector<CalibrationRow> calibration_rows(const SensorSet& set, const World& world,
                                                           const std::vector<int>& pixels,
                                                           const std::vector<std::string>& extra_columns = {});

/// Writes the header and rows. `with_material` adds the material column.
void write_calibration_csv(std::ostream& out, const std::vector<CalibrationRow>& rows, bool with_material,
                           const std::vector<std::string>& extra_columns = {});

/// A rail sweep: distances x sets per distance, either at a fixed discharge
/// (one read-out per set, pulses chosen per distance) or with a read-out
/// schedule (several read-outs per set).
struct RailSweep {
  std::vector<double> distances_m;
  int sets_per_distance = 10;
  std::optional<double> discharge_fraction;  ///< e.g. 0.4; unset: use `schedule`
  std::vector<int> schedule{20, 100, 200, 400, 700};
  std::vector<int> pixels{135, 136};
  double t_start_s = 3600.0;  ///< sensor time of the first set (warm by default)
  double set_period_s = 0.05;
  std::uint64_t first_index = 0;
};

[[nodiscard]] std::vector<CalibrationRow> run_sweep(const CalibrationRail& rail_template, const RailSweep& sweep,
                                                    const std::vector<std::string>& extra_columns = {});

}  // namespace tinyline::sim
