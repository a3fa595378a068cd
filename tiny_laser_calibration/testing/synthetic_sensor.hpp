// SPDX-License-Identifier: Apache-2.0
// A documented physical model of the sensor's two gated capacitors, used to
// make calibration data with known truth in the calibration tests (the
// project's simulator, sim/, is the sensor for everything else; this model is
// kept small and fixed so the tests' expectations cannot drift with it).
//
// Per laser pulse and pixel (thesis 3.2.2-3.3.4):
//   Td = tau(T) + 2 L / c  (+ undeclared delay effects)          arrival of the echo [ns]
//   tau(T) = tau_ref + kappa (T - T_ref)                         MOSFET driver delay, 3.3.4
//   emitted power f(s) = 0.04 + sin^2(pi s/T0) (0.4 + s/T0)      3.3.2: curved, skewed, not rectangular
//   Q1 = E G(T0 - Td),  Q2 = E (G(T0) - G(T0 - Td)),  G(t) = int_0^t f
//   E = E0 albedo cos(incidence) cos^4(theta_px) overlap(L) / L^2
//   overlap(L) = 1 - exp(-(L / L_overlap)^2)                     emitter/receiver parallax at close range
//   each capacitor also collects V = (ambient + leakage) per pulse
//   a = (Q1 + V) / Rsen_px,  b = Q2 + V                          so a Rsen - V = Q1 (Eq. 3.16 holds)
// Accumulation over p pulses is non-destructive: the five read-outs of a frame
// share one random walk of shot noise (variance shot_gain * charge); ADC noise
// is independent per read-out; values are quantised to 0.1 charge_unit (the
// wire) and clamp at the ADC ceiling.
//
// Undeclared effects (off by default), each a physical cause the declared model lacks:
//   material_bias      echo delay by surface reflectance, interpolated from Table 3.2
//   pixel_pattern      a fixed per-pixel gate skew (fixed-pattern offset)
//   time_drift         a slow delay drift with time since start, independent of the MCU temperature
//   supply_voltage     driver delay vs. laser supply voltage (thesis 3.3.4 names it); a `supply_v` column
//   capacitor_nonlinearity  each capacitor reads low near full scale: a (1 - eta a / full)
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <tiny_laser_calibration/data.hpp>

namespace tinyline::tiny_laser_calibration::testing {

struct SyntheticEffects {
  bool material_bias = false;
  bool pixel_pattern = false;
  double pixel_pattern_sd_m = 0.01;  ///< SD of the per-pixel offset [m]
  bool time_drift = false;
  double time_drift_m_per_ks = 0.012;  ///< [m per 1000 s]
  bool supply_voltage = false;         ///< adds the supply_v column and its delay effect
  double supply_delay_ns = 0.4;        ///< delay scale of the supply effect [ns]
  bool capacitor_nonlinearity = false;
  double nonlinearity_eta = 0.06;  ///< relative loss at full scale
  /// Always add a supply_v column (random, with no effect unless supply_voltage).
  bool supply_column = false;
};

struct SyntheticSensor {
  double t0_ns = 40.0;            ///< pulse width T0
  double tau_ref_ns = 16.0;       ///< driver delay at T_ref (after the hardware trim of 3.3.1)
  double kappa_ns_per_c = 0.064;  ///< delay drift: 1.6 ns over 25 degC (thesis: 1-2 ns over tens of degC)
  double t_ref_c = 48.0;          ///< warm temperature
  double ambient_c = 25.0;        ///< temperature at start
  double warmup_s = 300.0;        ///< warm-up time constant
  double e0 = 0.4;                ///< charge per pulse from white paper at 1 m, on axis [charge_unit m^2]
  double overlap_m = 0.15;
  double ambient_per_pulse = 0.002;  ///< [charge_unit per pulse], both capacitors
  double leak_per_pulse = 0.003;     ///< [charge_unit per pulse], both capacitors
  double rsen_sd = 0.02;             ///< per-pixel sensitivity ratio spread around 1
  double adc_sd = 0.15;              ///< [charge_unit]
  double shot_gain = 0.0008;         ///< shot-noise variance per unit charge [charge_unit]
  double full_scale = 250.0;         ///< ADC ceiling [charge_unit]
  bool quantise = true;              ///< round read-outs to 0.1 charge_unit as the wire does
  double focal_mm = 8.0;
  double pixel_pitch_mm = 0.02;  ///< 5.12 mm over 256 pixels
  SyntheticEffects effects;
  std::uint64_t seed = 1;  ///< per-pixel constants (Rsen, fixed pattern)
};

struct SyntheticMaterial {
  std::string name;
  double albedo = 1.0;  ///< relative to white paper (Table 3.2 reflectance / 6.92)
};
/// The nine materials of Table 3.2.
const std::vector<SyntheticMaterial>& table_3_2_materials();
/// Bias of Table 3.2 as a function of albedo [m] (interpolated in log albedo).
double material_bias_m(double albedo);

/// A calibration rail: a flat target, normal to the optical axis, visited at
/// each distance `passes` times in shuffled order.
struct RailPlan {
  std::vector<double> distances_m;  ///< default: 0.05 to 2.0 m every 5 cm
  std::vector<SyntheticMaterial> materials{{"white_paper", 1.0}};
  std::vector<int> pulses{20, 100, 200, 400, 700};  ///< read-outs per frame (the firmware's buffer)
  std::vector<int> pixels;                          ///< default: every 4th ranging pixel
  /// When > 0: one read-out per pixel and frame, its pulse count (a multiple of 10 in
  /// [10, 990]) chosen per pixel and distance so the fuller capacitor reaches this share
  /// of full scale: the thesis's fixed-discharge data (3.5: 0.4 and 0.2).
  double fixed_discharge = 0.0;
  int passes = 2;
  int frames_per_visit = 3;
  double frame_period_s = 0.03;
  double move_time_s = 15.0;  ///< time to move the target between visits
  std::uint64_t seed = 7;
};
RailPlan default_rail();

/// Generates the CSV rows of a rail run (all read-outs, saturated and dark ones included).
CalibrationDataset simulate_rail(const SyntheticSensor& sensor, const RailPlan& plan);

/// The per-pixel sensitivity ratios the model draws (seeded by sensor.seed).
std::vector<double> pixel_sensitivity_ratios(const SyntheticSensor& sensor);
/// The fixed-pattern offset of each pixel [m] (used when effects.pixel_pattern).
std::vector<double> pixel_pattern_m(const SyntheticSensor& sensor);

/// What a pixel reads with the laser off (ambient light and leakage only), noise-free:
/// the thesis measures Vle this way and Rsen from the ratio (3.3.3).
struct Charges;
Charges dark_charges(const SyntheticSensor& sensor, int pixel, int pulses);

/// Per-pulse expected charges of one pixel (no noise), for checks.
struct Charges {
  double a = 0.0, b = 0.0;
};
Charges expected_charges(const SyntheticSensor& sensor, double distance_m, double albedo, int pixel,
                         double temperature_c, int pulses);

}  // namespace tinyline::tiny_laser_calibration::testing
