// SPDX-License-Identifier: Apache-2.0
// The tiny TOF laser line sensor, per pixel and per measurement set
// (thesis 3.2-3.3). For every pixel: sub-rays across its width find the
// surfaces it sees; each return's energy follows range, incidence, albedo and
// specular lobe (1/(r_e r_rx), the emitter-to-point and point-to-receiver
// ranges, which differ by the baseline); its delay splits the curved 40 ns
// pulse between the two gated capacitors; a lens blur plus halo mixes
// neighbouring returns (mixed pixels, the emitter-side "distance drag" of
// 4.4.2; points the emitter cannot reach across the baseline stay dark).
// Charges accumulate over the pulses of a set and are read out
// non-destructively at several pulse counts, with shot and read noise,
// leakage, per-pixel sensitivity ratio, soft saturation and 12-bit
// quantisation. The driver delay drifts with a warm-up temperature, and other
// sensors' pulses that land in this sensor's gates add crosstalk.
//
// Core code: no bus, no I/O. Deterministic for a given seed and set index.
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include <sim/sensor_params.hpp>
#include <sim/world.hpp>

namespace tinyline::sim {

inline constexpr double kSpeedOfLight = 299792458.0;  ///< [m/s]
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Ground truth of one pixel, from its central ray.
struct PixelTruth {
  double range_m = kNaN;  ///< receiver to the first surface along the pixel's ray (NaN: none)
  ObjectId object = kNoObject;
  MaterialId material = kNoMaterial;
  double incidence_rad = kNaN;  ///< angle between the ray and the surface normal
  bool lit = false;             ///< the emitter reaches that point (not in the baseline's shadow)
  bool mixed = false;           ///< the pixel's blurred footprint spans several surfaces or > 2 cm of range
};

/// One non-destructive read-out of every pixel (dark pixels included).
struct Readout {
  int pulses = 0;
  double t_s = 0.0;       ///< time of the read-out since power-on
  std::vector<double> a;  ///< capacitor A discharge [charge_unit], quantised
  std::vector<double> b;  ///< capacitor B discharge [charge_unit], quantised
};

/// One measurement set: the read-outs of one accumulation.
struct SensorSet {
  std::uint64_t index = 0;
  double t_start_s = 0.0;      ///< accumulation start, since power-on
  double t_end_s = 0.0;        ///< last read-out
  double temperature_c = 0.0;  ///< MCU reading at the end (0.1 degC steps, with noise)
  double true_temperature_c = 0.0;
  bool laser_on = true;
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
  std::vector<Readout> readouts;
  std::vector<PixelTruth> truth;
  std::map<std::string, double> covariates;  ///< values of `covariate` effects
  int crosstalk_pulses = 0;                  ///< own pulses that caught another sensor's light in their gates
};

/// Another sensor emitting into the same world (for crosstalk). Pulses at
/// first_pulse_s + k / pulse_rate_hz (shared clock) while inside on_intervals.
struct ForeignEmitter {
  std::string name;
  Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
  EmitterParams emitter;
  double first_pulse_s = 0.0;
  double pulse_rate_hz = 25000.0;                       ///< its actual rate (nominal times its clock error)
  std::vector<std::pair<double, double>> on_intervals;  ///< [start, end) on the shared clock
};

struct MeasureOptions {
  bool noise = true;     ///< false: expected values (no shot/read noise, no quantisation)
  bool laser_on = true;  ///< false: a dark set (leakage, ambient, crosstalk only)
  /// Offset of this sensor's clock on the shared clock (crosstalk timing):
  /// shared time = sensor time + clock_offset_s.
  double clock_offset_s = 0.0;
};

/// Per-pulse expected charges of every pixel (before accumulation), for
/// factory calibration, tests and diagnostics.
struct PulseCharges {
  std::vector<double> qa, qb;   ///< signal per pulse into A and B (before R_sen) [charge_unit]
  std::vector<double> ambient;  ///< ambient per pulse per gate [charge_unit]
};

class TofLineSensor {
 public:
  /// Throws std::invalid_argument when params.validate() fails.
  explicit TofLineSensor(SensorParams params);
  ~TofLineSensor();
  TofLineSensor(const TofLineSensor& other) : TofLineSensor(other.params_) {}
  TofLineSensor& operator=(const TofLineSensor& other) { return *this = TofLineSensor(other.params_); }
  TofLineSensor(TofLineSensor&&) noexcept;
  TofLineSensor& operator=(TofLineSensor&&) noexcept;

  [[nodiscard]] const SensorParams& params() const { return params_; }
  [[nodiscard]] int pixels() const { return params_.lens.pixels; }
  [[nodiscard]] bool is_dark(int pixel) const;
  /// Ray angle of a pixel in the sensor's x-z plane [rad]: atan(u / f), u the
  /// pixel centre's offset from the line's middle (+x for higher indices).
  [[nodiscard]] double pixel_angle_rad(int pixel) const;
  /// Unit ray direction of a pixel in the sensor frame.
  [[nodiscard]] Eigen::Vector3d pixel_direction(int pixel) const;

  /// Sensor temperature (true value) at t_s since power-on.
  [[nodiscard]] double temperature_c(double t_s) const;
  /// Time to accumulate `pulses` [s].
  [[nodiscard]] double accumulation_time_s(int pulses) const { return pulses / params_.emitter.pulse_rate_hz; }
  /// Per-pixel constants drawn from the seed.
  [[nodiscard]] double sensitivity_ratio(int pixel) const;
  [[nodiscard]] double leakage_per_ms(int pixel) const;

  /// Fraction of a return that lands in gate A / gate B when it arrives Td
  /// after emission starts [ns] (curved pulse, diffusion tail, gate timing).
  [[nodiscard]] double gate_fraction_a(double td_ns) const;
  [[nodiscard]] double gate_fraction_b(double td_ns) const;

  /// Simulates one set. `pulses`: ascending read-out pulse counts (e.g. the
  /// raw-mode schedule). `index` seeds the set's noise (same index, same set).
  [[nodiscard]] SensorSet measure(const World& world, const Eigen::Isometry3d& T_world_sensor, double t_start_s,
                                  std::span<const int> pulses, std::uint64_t index,
                                  std::span<const ForeignEmitter> others = {},
                                  const MeasureOptions& options = {}) const;

  /// Expected per-pulse charges (no noise, no crosstalk) at time t_s.
  [[nodiscard]] PulseCharges pulse_charges(const World& world, const Eigen::Isometry3d& T_world_sensor, double t_s,
                                           std::vector<PixelTruth>* truth = nullptr) const;

  struct Impl;  ///< implementation detail (tables, per-pixel constants)

 private:
  SensorParams params_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace tinyline::sim
