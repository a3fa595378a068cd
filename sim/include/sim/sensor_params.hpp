// SPDX-License-Identifier: Apache-2.0
// Parameters of one simulated tiny TOF line sensor, with units. Defaults are
// the thesis-fidelity values of docs/simulator_fidelity.md (8 mm lens);
// config/sensors/*.yaml override them per instance.
//
// Sensor frame: z forward (optical axis), x along the pixel line, y = z cross x.
// The receiver's lens centre is the origin; the line laser sits at
// (baseline_m, 0, 0) and fans out in the x-z plane.
//
// "Declared" physics (what the calibration model of calibration.hpp
// represents: ratio with sensitivity ratio and leakage, curved pulse,
// temperature offset) lives in the structs below. Anything else is an
// Effect in `effects`, off unless listed (see effects.hpp).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <sim/effects.hpp>

#include <tinyline/common/status.hpp>

namespace tinyline::sim {

class YamlNode;

struct LensParams {
  double focal_mm = 8.0;              ///< receiver focal length (3.6 or 8 mm shipped)
  double sensor_length_mm = 5.12;     ///< length of the 256 effective pixels
  int pixels = 272;                   ///< transmitted pixels
  int dark_pixels = 8;                ///< masked pixels at each end (no light)
  int subrays_per_pixel = 4;          ///< rays across each pixel's width (mixed pixels)
  double psf_sigma_px = 0.5;          ///< Gaussian blur of the lens + diffraction [pixels]
  double halo_fraction = 0.01;        ///< share of each pixel's light scattered into a wide halo
  double halo_length_px = 8.0;        ///< e-folding length of the halo [pixels]
  double vignetting_cos_power = 4.0;  ///< relative illumination cos^n(field angle)
  double pixel_height_mm = 0.5;       ///< pixel height across the line (vertical field of view)

  [[nodiscard]] double pitch_mm() const { return sensor_length_mm / (pixels - 2 * dark_pixels); }
};

struct EmitterParams {
  double baseline_m = 0.012;          ///< emitter offset along +x from the receiver
  double fan_half_angle_deg = 22.0;   ///< line laser fan half angle (flat inside)
  double fan_edge_deg = 2.0;          ///< width of the fan's soft edge
  double sheet_thickness_mm = 1.0;    ///< laser sheet thickness at the emitter (crosstalk geometry)
  double sheet_divergence_deg = 0.3;  ///< full divergence of the sheet across the fan plane
  double pulse_width_ns = 40.0;       ///< T0, emitted pulse length
  double pulse_rise_exponent = 1.0;   ///< pulse power ~ s^rise (1-s)^fall, s in [0,1]
  double pulse_fall_exponent = 1.4;
  double diffusion_tail_ns = 1.0;  ///< slow photo-charge (exponential tail) [ns]
  double pulse_rate_hz = 25000.0;  ///< laser pulse repetition rate (0.1% duty at 40 ns)
  /// Received (a+b) per pulse [charge_unit] from a Lambertian albedo-1 target
  /// at 1 m, normal incidence, on the optical axis. Sets the radiometric scale.
  double charge_per_pulse_1m = 0.787;
};

struct PixelParams {
  double gate_split_ns = 21.0;         ///< gate A closes / gate B opens this long after emission starts
  double sensitivity_ratio = 1.0;      ///< mean R_sen (Eq. 3.16): raw a = (q_A + V_le) / R_sen
  double sensitivity_ratio_sd = 0.03;  ///< pixel-to-pixel spread of R_sen
  /// Mean V_le growth [charge_unit per ms of accumulation]. The public
  /// driver's validity rule (a + b > 10 + 0.4 pulses/10) implies the two
  /// capacitors leak well under 0.04 per pulse together.
  double leakage_per_ms = 0.6;
  double leakage_sd = 0.1;    ///< relative pixel-to-pixel spread of the leakage
  double prnu_sd = 0.02;      ///< photo-response non-uniformity (relative gain spread)
  double full_scale = 250.0;  ///< saturation of a capacitor read-out [charge_unit]
  double knee = 225.0;        ///< soft compression starts here [charge_unit]
  /// Charge-to-voltage non-linearity of the read-out: a read-out v of the charge
  /// q the capacitor holds (after its saturation) is q * (1 - nonlinearity * q /
  /// full_scale), so it tops out at full_scale * (1 - nonlinearity).
  double nonlinearity = 0.0;
  double read_noise = 0.15;       ///< ADC + reset noise per read-out [charge_unit rms]
  double shot_noise_gain = 4e-4;  ///< shot-noise variance per unit of collected charge [charge_unit]
  /// Zero-mean charge each gate cycle adds (reset and transfer noise of the
  /// photodiode, drained and refilled every pulse) [charge_unit rms per pulse].
  double transfer_noise_per_pulse = 0.045;
  /// Constant offsets of the two read-out channels (each capacitor has its
  /// own buffer and ADC) [charge_unit]; they do not grow with the pulses, so
  /// the declared leakage V_le * pulses cannot absorb them.
  double adc_offset_a = 0.0;
  double adc_offset_b = -1.75;
  double adc_lsb = 0.1;    ///< quantisation step [charge_unit] (the wire carries 10x)
  double adc_max = 409.5;  ///< ADC full range [charge_unit] (12 bit)
};

struct ThermalParams {
  double ambient_c = 25.0;             ///< temperature at power-on
  double warm_c = 48.0;                ///< saturation temperature after warm-up
  double time_constant_s = 120.0;      ///< first-order warm-up time constant
  double reference_c = 48.0;           ///< temperature at which the gate timing was aligned
  double delay_drift_ns_per_c = 0.05;  ///< MOSFET driver delay drift (1-2 ns over tens of degC)
  double reading_noise_c = 0.05;       ///< MCU temperature sensor noise [degC rms]
};

struct AcquisitionParams {
  std::vector<int> raw_pulses{20, 100, 200, 400, 700};            ///< raw mode read-outs (5 per set)
  std::vector<int> distance_pulses{10, 100, 200, 400, 550, 700};  ///< firmware buffer (distance mode)
};

struct EnvironmentParams {
  /// Ambient light collected per gate per pulse [charge_unit] from an
  /// albedo-1 surface (indoor light through the 905 nm filter).
  double ambient_charge_per_pulse = 0.0;
};

/// Which firmware the sensor's MCU runs (docs/simulator.md, "Firmware profiles").
enum class FirmwareProfile {
  kThesisRaw,  ///< raw sets of read-outs and the host commands of Algorithms 1 and 4 (the thesis's firmware)
  kPublished,  ///< the published STM32 firmware: distance frames only, repeated by circular DMA, commands ignored
};
[[nodiscard]] const char* to_string(FirmwareProfile p);
/// "thesis_raw" or "published"; nullopt for anything else.
[[nodiscard]] std::optional<FirmwareProfile> firmware_profile_from_string(std::string_view s);

/// The firmware and the constants of the published one (its Src/main.c and
/// Src/itcallback.cpp); the thesis profile uses `acquisition` only.
struct FirmwareParams {
  FirmwareProfile profile = FirmwareProfile::kThesisRaw;
  double tick_s = 100e-6;           ///< published: timer interrupt period (one count of the pulse counter)
  int cycle_ticks = 1001;           ///< published: ticks per accumulation cycle (it sends when the counter passes 1000)
  double sensitivity_ratio = 1.04;  ///< published: SR, the factor on capacitor A's discharge
  int compensated_pixel = 176;      ///< published: the pixel whose A discharge is scaled once more ...
  double compensated_pixel_factor = 1.04;  ///< ... by this (a defect of the authors' unit, compensated by hand)
  /// published: discharge [charge_unit] from which a capacitor counts as
  /// saturated (the firmware's ADC output below 2200 counts, from a reset
  /// level near 4000); a saturated read-out leaves the pixel's earlier value.
  double saturation_charge = 180.0;

  [[nodiscard]] double cycle_s() const { return tick_s * cycle_ticks; }
};

struct SensorParams {
  std::string name = "tiny_tof";
  LensParams lens;
  EmitterParams emitter;
  PixelParams pixel;
  ThermalParams thermal;
  AcquisitionParams acquisition;
  EnvironmentParams environment;
  FirmwareParams firmware;
  std::vector<EffectSpec> effects;  ///< undeclared extras, off unless listed
  std::uint64_t seed = 1;           ///< per-pixel constants and noise

  /// Why the parameters cannot work (InvalidArgument); ok when they can.
  common::Status validate() const;
};

/// Reads a sensor YAML (see config/sensors/). Unknown keys, wrong types and
/// out-of-range values throw ConfigError naming file, line and field.
[[nodiscard]] SensorParams load_sensor_params(const std::string& path);
/// Applies the keys of `node` on top of `base` (same layout as the file).
void apply_sensor_params(const YamlNode& node, SensorParams& base);
/// The YAML text of `p` (all keys), for docs and round trips.
[[nodiscard]] std::string to_yaml(const SensorParams& p);

}  // namespace tinyline::sim
