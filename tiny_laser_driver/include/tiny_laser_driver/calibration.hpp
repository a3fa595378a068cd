// SPDX-License-Identifier: Apache-2.0
// The calibration model of the tiny TOF line sensor: what maps one pixel's
// read-out (two capacitor discharges at a pulse count, the MCU temperature)
// to a distance. One implementation, used by the calibration package to fit
// and by the driver at run time: the model the tool writes is the model the
// driver applies.
//
// Declared model (thesis 3.2.4-3.3.4):
//   X = (b - Vle(p)) / ((a*Rsen - Vle(p)) + (b - Vle(p)))      charge ratio, Eq. 3.16 / 3.18
//   L = P(X) + c_T * (T_stable - T)                            polynomial, Eq. 3.18; temperature, 3.3.4
// fitted with per-distance weights K_i (multi-discharge, Eq. 3.20). Terms
// found by the residual analysis (named covariate + form) are added on top.
//
// This header is the contract between the calibration tool and the driver.
// Extend it; do not break it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

namespace tinyline::tiny_laser_driver {

/// What the sensor can measure at all: L in [0, c T0 / 2] with T0 = 40 ns (Eq. 3.4).
/// A calibrated distance outside it is no measurement: the driver flags such a
/// pixel out of range, and a calibration that maps its usable ratio range far
/// outside it is refused at load.
inline constexpr double kPhysicalMinDistanceM = 0.0;
inline constexpr double kPhysicalMaxDistanceM = 6.0;
/// The largest polynomial a calibration file may hold (`tinyline calib fit
/// --degree` goes to 12).
inline constexpr std::size_t kMaxPolynomialCoefficients = 13;
/// The largest calibration file the loader reads [bytes] (a fitted one is ~30 KB).
inline constexpr std::uint64_t kMaxCalibrationFileBytes = 1u << 20;

/// One read-out of one pixel. Charges in the sensor's charge unit (the wire
/// carries ten times this unit as int16).
struct Readout {
  double a = 0.0;              ///< capacitor A discharge [charge_unit]
  double b = 0.0;              ///< capacitor B discharge [charge_unit]
  int pulses = 0;              ///< accumulated laser pulses
  double temperature_c = 0.0;  ///< MCU temperature [degC]
  int pixel = 0;               ///< 0-271 (dark pixels included)
  double t_s = 0.0;            ///< time since the sensor started [s]
  /// Values of the model's extra covariates, in the order of
  /// CalibrationModel::extra_covariates() (empty when the model has none).
  std::vector<double> extra;
};

/// The declared validity rule (public driver): a read-out is usable when both
/// charges are inside (low, high) and a + b exceeds min_sum + per_pulse * pulses/10.
struct ValidityRule {
  double low = 10.0;       ///< [charge_unit] below: too little light
  double high = 230.0;     ///< [charge_unit] above: saturated
  double min_sum = 10.0;   ///< [charge_unit]
  double per_pulse = 0.4;  ///< [charge_unit per 10 pulses]

  enum class Verdict { kValid, kSaturated, kTooDark };
  [[nodiscard]] Verdict check(const Readout& r) const;
};
std::string_view to_string(ValidityRule::Verdict v);

/// Everything the model computes for one read-out (CalibrationModel::evaluate).
struct CalibrationEvaluation {
  enum class Status {
    kValid,             ///< distance_m is the calibrated distance
    kSaturated,         ///< the validity rule says saturated
    kTooDark,           ///< the validity rule says too little light (or a non-positive corrected sum)
    kOutOfRange,        ///< the charge ratio lies outside the range the model was fitted on
    kMissingCovariate,  ///< a term needs a covariate the read-out lacks (term skipped), or the temperature
                        ///< is NaN (offset of 3.3.4 not applied); distance_m is still given
  };
  Status status = Status::kTooDark;
  double distance_m = std::numeric_limits<double>::quiet_NaN();  ///< NaN unless kValid / kMissingCovariate
  /// Distance of the declared part alone (Eq. 3.18 + temperature), before discovered terms [m].
  double declared_distance_m = std::numeric_limits<double>::quiet_NaN();
  double ratio = std::numeric_limits<double>::quiet_NaN();  ///< charge ratio X of Eq. 3.16
  /// The sensor's relative reflectance figure: declared_distance_m^2 * (a + b) / pulses
  /// [charge_unit m^2 / pulse] (the public driver's figure in other units).
  double reflectance = std::numeric_limits<double>::quiet_NaN();
  /// Light returned per pulse relative to the calibration target's at the same distance and
  /// pixel (1 = like the target; white paper calibrations read other materials' albedo
  /// relative to white paper). NaN when the model carries no amplitude reference.
  double albedo = std::numeric_limits<double>::quiet_NaN();
  /// The range's SD from the calibration's noise law (section 3.5) at this read-out's
  /// light [m]; NaN when the model carries no law or there is no distance.
  double range_sd_m = std::numeric_limits<double>::quiet_NaN();
};
std::string_view to_string(CalibrationEvaluation::Status s);

class CalibrationModel {
 public:
  /// Loads a calibration YAML (as written by `tinyline calib fit`). Throws
  /// std::runtime_error naming the file, line and field on bad content: an
  /// unknown or repeated key, a missing section or field, a bad value, more
  /// than kMaxPolynomialCoefficients coefficients, or a polynomial that reads
  /// far outside the physical range over its usable ratio range. `load` reads
  /// only a regular file of at most kMaxCalibrationFileBytes.
  static CalibrationModel load(const std::string& path);
  static CalibrationModel from_yaml(const std::string& text, const std::string& source_name);
  /// Writes the model; throws std::runtime_error on I/O failure.
  void save(const std::string& path) const;
  std::string to_yaml() const;

  /// Distance along the pixel's ray [m]; NaN when the read-out is not valid
  /// under the model's validity rule.
  [[nodiscard]] double distance_m(const Readout& r) const;
  /// distance_m() with the reason when there is none, and the intermediate figures.
  /// A term whose extra covariate is missing (r.extra too short or NaN) is skipped and
  /// reported as kMissingCovariate, with the distance of the remaining terms.
  [[nodiscard]] CalibrationEvaluation evaluate(const Readout& r) const;
  [[nodiscard]] const ValidityRule& validity() const;
  /// Names of further covariates the model's discovered terms use.
  [[nodiscard]] const std::vector<std::string>& extra_covariates() const;
  /// One line per part of the model ("degree-6 polynomial in X on [0.35, 0.80]", one per term).
  [[nodiscard]] std::string describe() const;

  /// The calibration of a real sensor as the public driver ships it
  /// (public_driver_sensors.hpp): distance_cm = sum_i poly[i] k^(6-i)
  /// + offsets, k = b / (a + b), plus (stable - t) * sensi with t in 0.1 degC.
  /// `poly` and `offsets_added` are highest power first.
  static CalibrationModel from_public_driver(const std::vector<double>& poly, const std::vector<double>& offsets_added,
                                             double stable_temperature_decic, double temperature_sensi_cm_per_decic);

  // The representation is the calibration tool's business (see calibration.cpp).
  struct Impl;
  CalibrationModel();
  ~CalibrationModel();
  CalibrationModel(const CalibrationModel&);
  CalibrationModel& operator=(const CalibrationModel&);
  CalibrationModel(CalibrationModel&&) noexcept;
  CalibrationModel& operator=(CalibrationModel&&) noexcept;
  Impl& impl() { return *impl_; }
  const Impl& impl() const { return *impl_; }

 private:
  Impl* impl_;
};

}  // namespace tinyline::tiny_laser_driver
