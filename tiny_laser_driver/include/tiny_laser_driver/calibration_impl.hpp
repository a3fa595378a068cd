// SPDX-License-Identifier: Apache-2.0
// The representation behind CalibrationModel: the declared model's parameters
// and the terms the residual analysis added. The fitter fills it; the driver
// only needs calibration.hpp. Units are in the names.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <tiny_laser_driver/calibration.hpp>

namespace tinyline::tiny_laser_driver {

/// Covariates every read-out carries (derived from its own fields and the
/// declared model), plus named extra columns.
enum class Covariate {
  kPixel,              ///< "pixel": pixel index 0-271
  kTime,               ///< "t_s": time since the sensor started [s]
  kPulses,             ///< "pulses": accumulated pulses of the read-out
  kAmplitude,          ///< "amplitude": a + b [charge_unit]
  kAmplitudePerPulse,  ///< "amplitude_per_pulse": (a + b) / pulses [charge_unit]
  kRatio,              ///< "ratio": the charge ratio X of Eq. 3.16
  kTemperature,        ///< "temperature_c": MCU temperature [degC]
  kReflectance,        ///< "reflectance": declared distance^2 * (a + b) / pulses [charge_unit m^2]
  kAlbedo,             ///< "albedo": (a + b) / pulses relative to the calibration target's at that distance and pixel
  kExtra,              ///< a further numeric column, by name (Readout::extra)
  // Covariates of the terms that act on the charges (not in builtin_covariates()):
  kOne,          ///< "one": 1 (a constant charge, or one per pulse)
  kPixelParity,  ///< "pixel_parity": pixel % 2
  kPixelBank,    ///< "pixel_bankN": (pixel - 8) / N, the bank of N effective pixels it is in
  kPixelIs,      ///< "pixel_isN": 1 for pixel N, else 0 (a single odd pixel)
  kCharge,       ///< "charge": the capacitor's own read-out (the readout form only)
};

/// Name used in CSV headers, YAML and reports ("pixel", "t_s", ...); "" for kExtra.
std::string_view covariate_name(Covariate c);
/// The built-in covariate of that name, or kExtra when it names no built-in one.
Covariate covariate_from_name(std::string_view name);
/// Built-in covariates in report order.
const std::vector<Covariate>& builtin_covariates();
/// N of "pixel_bankN" / "pixel_isN" (0 for any other name).
int covariate_parameter(std::string_view name);

/// Shapes a discovered term may take. The first three add to the distance;
/// the others act on the two charges before Eq. 3.16, where the physics puts
/// them, with g(z) piecewise linear on knots as for kSmooth (values in
/// charge_unit, charge_unit per pulse, or a relative gain):
enum class TermForm {
  kSmooth,                ///< g(z): piecewise linear on knots, constant beyond the end knots
  kTable,                 ///< offset per integer value of z (0 for values not in the table)
  kAmplitudeInteraction,  ///< g(z) * u, u = (a + b - amplitude_reference) / amplitude_scale
  kChargeA,               ///< capacitor A holds g(z) extra charge: a - g(z)
  kChargeB,               ///< b - g(z)
  kChargeBoth,            ///< both: a - g(z), b - g(z)
  kChargeAPerPulse,       ///< g(z) extra charge per pulse: a - g(z) pulses
  kChargeBPerPulse,       ///< b - g(z) pulses
  kChargeBothPerPulse,    ///< a - g(z) pulses, b - g(z) pulses (ambient light, leakage)
  kGainA,                 ///< capacitor A reads 1 + g(z) times its charge: a / (1 + g(z))
  kGainB,                 ///< b / (1 + g(z))
  kReadout,               ///< read-out nonlinearity of both: v + g(v), z = the read-out v itself ("charge")
  /// Time walk with the light: sum_k values[k] ln^(k+1)(z / reference), z held inside knots = [lo, hi]
  /// (the light levels it was fitted on; constant beyond, as kSmooth). Adds to the distance.
  kLightWalk,
};
std::string_view to_string(TermForm f);
std::optional<TermForm> term_form_from_string(std::string_view s);
/// The form acts on the charges (before Eq. 3.16) rather than on the distance.
bool acts_on_charges(TermForm f);

/// One term added on top of the declared model: distance += term(z).
struct CalibrationTerm {
  std::string covariate;  ///< covariate name (built-in or extra column)
  TermForm form = TermForm::kSmooth;
  // kSmooth, kAmplitudeInteraction: values at increasing knots.
  std::vector<double> knots;
  std::vector<double> values;  ///< [m] (kSmooth), [m per unit of u] (kAmplitudeInteraction), [m per ln^k] (kLightWalk)
  // kTable: sorted integer keys and their offsets [m].
  std::vector<long> keys;
  std::vector<double> offsets_m;
  // kAmplitudeInteraction
  double amplitude_reference = 0.0;  ///< [charge_unit]
  double amplitude_scale = 1.0;      ///< [charge_unit]
  // kLightWalk: the light level z at which the walk is zero (the calibration target's).
  double reference = 1.0;
  // Held-out figures recorded when the term was accepted (informational; NaN if unknown).
  double rmse_before_m = std::numeric_limits<double>::quiet_NaN();
  double rmse_after_m = std::numeric_limits<double>::quiet_NaN();

  // Resolved on load / when added to a model.
  Covariate kind = Covariate::kExtra;
  int extra_index = -1;     ///< index into Readout::extra for kExtra; N of kPixelBank / kPixelIs
  bool dense_keys = false;  ///< keys are first_key, first_key + 1, ...: a table lookup is an index
  long first_key = 0;

  /// Number of linear coefficients (the fitter's basis size).
  [[nodiscard]] std::size_t basis_size() const;
  /// Basis functions at covariate value z and amplitude (a + b): appends (column, value)
  /// pairs with columns relative to the term's first coefficient.
  void basis(double z, double amplitude, std::vector<std::pair<std::size_t, double>>& out) const;
  /// Sets the term's coefficients from a vector of basis_size() values.
  void set_coefficients(const double* c);
  /// The term's value at z for a read-out of amplitude (a + b) [m].
  [[nodiscard]] double value(double z, double amplitude) const;
};

/// What the calibration target returned per pulse, by declared distance and
/// pixel: the reference of the albedo covariate. It holds the 1/L^2 fall-off,
/// the emitter/receiver overlap at close range and the lens vignetting, which
/// the thesis's reflectance figure (L^2 (a + b) / pulses) leaves in.
struct AmplitudeReference {
  std::vector<double> knots_m;           ///< declared distances [m], increasing
  std::vector<double> log_amplitude;     ///< ln((a + b) / pulses) at the knots [ln charge_unit]
  std::vector<double> pixel_log_offset;  ///< empty, or per pixel (0-271) [ln]
  [[nodiscard]] bool empty() const { return knots_m.empty(); }
  /// (a + b) / pulses over the reference at `declared_m` (NaN when empty or not positive).
  [[nodiscard]] double albedo(const Readout& r, double declared_m) const;
};

/// The read-out noise as the charge ratio sees it (section 3.5):
/// var(X) = (shot S + per_pulse p + read) / S^2, S = a + b and p the pulses of
/// the read-out: shot noise (var(X) ~ 1/S, SD ~ S^-0.5), the transfer noise that
/// accumulates per gate cycle, and the read-out's own. The range's SD is
/// sqrt(var(X)) |dL/dX| of the polynomial: what the driver publishes per pixel.
struct NoiseLaw {
  double shot = 0.0;       ///< [charge_unit]
  double per_pulse = 0.0;  ///< [charge_unit^2 per pulse]
  double read = 0.0;       ///< [charge_unit^2]
  [[nodiscard]] bool empty() const { return !(shot > 0.0 || per_pulse > 0.0 || read > 0.0); }
  /// SD of X at light S after p pulses (NaN when empty or S is not positive).
  [[nodiscard]] double ratio_sd_at(double sum, int pulses) const;
};

/// Provenance and in-sample figures written beside the model (informational).
struct CalibrationFitInfo {
  std::string data;                                          ///< data file the model was fitted on
  std::size_t rows = 0;                                      ///< valid read-outs used
  double rmse_m = std::numeric_limits<double>::quiet_NaN();  ///< in-sample
  double heldout_rmse_before_m = std::numeric_limits<double>::quiet_NaN();
  double heldout_rmse_after_m = std::numeric_limits<double>::quiet_NaN();
  std::string weighting;  ///< K_i of Eq. 3.20
};

struct CalibrationModel::Impl {
  ValidityRule validity;

  // Eq. 3.16: X = (b - Vle(p)) / ((a Rsen - Vle(p)) + (b - Vle(p))), Vle(p) = offset + per_pulse * p.
  double sensitivity_ratio = 1.0;
  std::vector<double> sensitivity_ratio_per_pixel;  ///< empty, or one per pixel (0-271)
  double leakage_offset = 0.0;                      ///< [charge_unit]
  double leakage_per_pulse = 0.0;                   ///< [charge_unit per pulse]
  /// X outside [ratio_min, ratio_max] widened by ratio_margin of its span is out of range:
  /// a polynomial is meaningless beyond the data it was fitted on.
  double ratio_min = 0.0;
  double ratio_max = 1.0;
  double ratio_margin = 0.05;

  // Eq. 3.18: L = sum_k poly_m[k] u^k, u = (X - poly_center) / poly_scale (scaled for conditioning).
  double poly_center = 0.0;
  double poly_scale = 1.0;
  std::vector<double> poly_m{0.0};

  // 3.3.4: L += temperature_coef_m_per_c * (temperature_reference_c - T).
  double temperature_reference_c = 48.0;
  double temperature_coef_m_per_c = 0.0;

  AmplitudeReference amplitude_reference;  ///< for the albedo covariate and evaluation output
  NoiseLaw noise;                          ///< the per-pixel range uncertainty (empty: none published)

  std::vector<CalibrationTerm> terms;
  std::vector<std::string> extra_covariates;  ///< derived from terms (resolve())
  bool has_charge_terms = false;              ///< derived from terms (resolve())
  CalibrationFitInfo info;

  /// Charge ratio X (NaN when the corrected sum is not positive), after the
  /// terms that act on the charges.
  [[nodiscard]] double ratio(const Readout& r) const;
  /// Eq. 3.16 on given charges.
  [[nodiscard]] static double charge_ratio(double a, double b, int pulses, double rsen, double leakage_offset,
                                           double leakage_per_pulse);
  /// The read-out's charges as the declared model expects them: the charge
  /// terms undone in the reverse order of the physics (read-out, then gain,
  /// then added charge). False when a term's covariate is missing (that term skipped).
  static bool correct_charges(const std::vector<CalibrationTerm>& terms, const Readout& r, double& a, double& b);
  [[nodiscard]] double sensitivity_ratio_of(int pixel) const;
  /// Eq. 3.18 in X.
  [[nodiscard]] double polynomial_m(double x) const;
  /// dL/dX of Eq. 3.18 at ratio x [m per unit of X].
  [[nodiscard]] double polynomial_slope_m(double x) const;
  /// Polynomial + temperature offset for ratio x [m].
  [[nodiscard]] double declared_m(double x, double temperature_c) const;
  /// Value of covariate `kind` for a read-out (extra_index for kExtra), given its
  /// ratio and declared distance. NaN when unavailable.
  [[nodiscard]] static double covariate_value(Covariate kind, int extra_index, const Readout& r, double x,
                                              double declared_m, const AmplitudeReference& reference);
  /// Resolves term covariates and rebuilds extra_covariates (kept in first-use order).
  void resolve();
};

}  // namespace tinyline::tiny_laser_driver
