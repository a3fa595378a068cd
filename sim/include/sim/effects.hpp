// SPDX-License-Identifier: Apache-2.0
// Pluggable effects: physics a sensor can carry on top of the declared model,
// listed per sensor instance in its YAML (`effects:`), off unless listed.
// Most are effects the calibration model (calibration.hpp) does NOT declare,
// so tests can check that the residual analysis finds them; each shifts the
// timing of the received light (ns) in a way tied to one covariate:
//
//  type             covariate it hides behind        form
//  trap_delay       amplitude per pulse (material)   share eps/(I+eps) of the charge released late
//  material_bias    material (text column)           extra optical path per material (subsurface)
//  fixed_pattern    pixel index                      per-pixel gate skew (random + linear ramp)
//  range_walk       amplitude per pulse              delay = k * log10(I / I_ref)
//  time_drift       time since start                 linear drift + optional sine
//  covariate        an extra measured column         delay = k * (value - mean); value reported
//  temperature_lag  temperature and its rate         driver temperature lags the MCU reading
//
// and one type that acts on the capacitors' charges instead of the timing
// (`charge`, ChargeEffect): ambient light that follows a measured covariate,
// extra leakage or a gain on one capacitor of a group of pixels.
//
// trap_delay is what the fidelity loop found behind Table 3.2 (see
// docs/simulator_fidelity.md); the thesis-fidelity sensor lists it.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <variant>
#include <vector>

namespace tinyline::sim {

/// Charge trapping in the pixel's transfer path: per pulse a share
/// capacity/(I + capacity) of the photo-charge (I = the pixel's charge per
/// pulse) is held and released release_delay_ns later. Dim returns are delayed
/// most: a positive range bias that fades with intensity (Table 3.2's pattern).
struct TrapDelayEffect {
  double capacity_per_pulse = 0.05;  ///< [charge_unit per pulse]
  double release_delay_ns = 1.8;
};

/// Subsurface scattering: each listed material returns light from below its
/// surface, adding path_mm of optical path (round trip counted once).
struct MaterialBiasEffect {
  std::map<std::string, double> path_mm;  ///< material name -> extra path [mm]
};

/// Per-pixel gate timing skew: random N(0, sigma_ps) per pixel plus a linear
/// ramp from -ramp_ps/2 (pixel 0) to +ramp_ps/2 (last pixel).
struct FixedPatternEffect {
  double sigma_ps = 100.0;
  double ramp_ps = 0.0;
  std::uint64_t seed = 7;
};

/// Amplitude-dependent timing: delay = ns_per_decade * log10(I / reference), I
/// the pixel's charge per pulse, clamped to +-max_ns.
struct RangeWalkEffect {
  double ns_per_decade = 0.3;
  double reference_charge_per_pulse = 1.0;
  double max_ns = 2.0;
};

/// Slow drift of the timing with time since power-on.
struct TimeDriftEffect {
  double ns_per_hour = 1.0;
  double sine_amplitude_ns = 0.0;
  double sine_period_s = 600.0;
};

/// A covariate measured alongside (reported per set under `name`): a sine of
/// `amplitude` around `mean` with period_s plus a random walk; the timing
/// shifts by ns_per_unit * (value - mean).
struct CovariateEffect {
  std::string name = "humidity_pct";
  double mean = 50.0;
  double amplitude = 15.0;
  double period_s = 300.0;
  double random_walk_per_sqrt_s = 0.0;
  double ns_per_unit = 0.02;
};

/// The MOSFET driver's temperature follows the MCU reading with a first-order
/// lag, so the delay drift depends on the temperature's history, not its value.
struct TemperatureLagEffect {
  double time_constant_s = 60.0;
};

/// Pixels an effect applies to: the listed ones, a range, a parity, or (all
/// empty) every pixel.
struct PixelGroup {
  std::vector<int> pixels;    ///< these pixels (e.g. {176})
  int first = -1, last = -1;  ///< a bank [first, last] (both >= 0 to use)
  int parity = -1;            ///< 0 even, 1 odd, -1 any
  [[nodiscard]] bool contains(int pixel) const;
};

/// An effect on the two capacitors' charges (Eq. 3.16's inputs), not on the
/// timing. Kinds:
///  ambient    both capacitors collect per_pulse * value extra charge per pulse,
///             value the current value of the `covariate` effect named `covariate`
///             (e.g. an ambient-light level in klux; its column may or may not be
///             recorded): the firmware's ambient subtraction, undone
///  leakage    capacitor `capacitor` of `pixels` collects per_pulse extra per pulse
///  gain       capacitor `capacitor` of `pixels` reads `gain` times its charge
///             (the published firmware's hand-made factor on pixel 176)
struct ChargeEffect {
  enum class Kind { kAmbient, kLeakage, kGain };
  enum class Capacitor { kA, kB, kBoth };
  Kind kind = Kind::kLeakage;
  Capacitor capacitor = Capacitor::kB;
  double per_pulse = 0.0;  ///< [charge_unit per pulse] (ambient: per unit of the covariate)
  double gain = 1.0;
  std::string covariate;  ///< ambient: the `covariate` effect whose value drives it
  PixelGroup pixels;
};

using EffectSpec = std::variant<TrapDelayEffect, MaterialBiasEffect, FixedPatternEffect, RangeWalkEffect,
                                TimeDriftEffect, CovariateEffect, TemperatureLagEffect, ChargeEffect>;

/// Adds the charge effects to the mean charges of one read-out of `pixel` at
/// `pulses` (before noise); `covariates` are the set's covariate values.
void apply_charge_effects(const std::vector<const ChargeEffect*>& effects, int pixel, int pulses,
                          const std::map<std::string, double>& covariates, double& a, double& b);

/// "trap_delay", "material_bias", ...
[[nodiscard]] const char* effect_type(const EffectSpec& e);
[[nodiscard]] std::vector<std::string> effect_types();

}  // namespace tinyline::sim
