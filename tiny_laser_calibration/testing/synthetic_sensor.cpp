// SPDX-License-Identifier: Apache-2.0
#include "synthetic_sensor.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <random>

#include <tiny_laser_driver/protocol.hpp>

namespace tinyline::tiny_laser_calibration::testing {

using tiny_laser_driver::kPixels;

namespace {

constexpr double kLightMPerNs = 0.299792458;
constexpr int kShapeSteps = 4000;

// Emitted power over the pulse: a slow sin^2 rise, skewed late, on a small
// pedestal (thesis 3.3.2: the power is "more like a quadratic function" than
// constant). Far targets sample its rising edge, which bends L(X) the way the
// real sensors' polynomials bend (steep near X = 0.8, the public driver's sensors).
double pulse_power(double s01) {
  const double s = std::sin(M_PI * s01);
  return 0.04 + s * s * (0.4 + s01);
}

// Cumulative emitted energy G(t) for t in [0, T0], tabulated once.
struct PulseIntegral {
  std::array<double, kShapeSteps + 1> g{};
  PulseIntegral() {
    g[0] = 0.0;
    for (int i = 1; i <= kShapeSteps; ++i) {
      const double s0 = (i - 1.0) / kShapeSteps, s1 = static_cast<double>(i) / kShapeSteps;
      g[static_cast<std::size_t>(i)] =
          g[static_cast<std::size_t>(i - 1)] + 0.5 * (pulse_power(s0) + pulse_power(s1)) / kShapeSteps;
    }
  }
  // Fraction of the pulse energy emitted before s01 (0-1 of T0).
  double fraction(double s01) const {
    s01 = std::clamp(s01, 0.0, 1.0);
    const double pos = s01 * kShapeSteps;
    const auto i = static_cast<std::size_t>(std::min(pos, kShapeSteps - 1.0));
    const double t = pos - static_cast<double>(i);
    return ((1.0 - t) * g[i] + t * g[i + 1]) / g[kShapeSteps];
  }
};
const PulseIntegral& pulse_integral() {
  static const PulseIntegral p;
  return p;
}

double ray_angle(const SyntheticSensor& s, int pixel) {
  const double offset_mm = (pixel - (kPixels - 1) / 2.0) * s.pixel_pitch_mm;
  return std::atan(offset_mm / s.focal_mm);
}

struct PixelConstants {
  std::vector<double> rsen, pattern_m;
};
PixelConstants pixel_constants(const SyntheticSensor& s) {
  std::mt19937_64 rng(s.seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  PixelConstants c;
  for (std::size_t i = 0; i < kPixels; ++i) {
    c.rsen.push_back(1.04 + s.rsen_sd * n01(rng));
    c.pattern_m.push_back(s.effects.pixel_pattern_sd_m * n01(rng));
  }
  return c;
}

double supply_delay_ns(const SyntheticSensor& s, double volts) {
  // Gate-driver propagation delay grows as the supply nears the threshold (3.5 V).
  return s.effects.supply_delay_ns * ((5.0 - 3.5) / (volts - 3.5) - 1.0);
}

struct Echo {
  double q1 = 0.0, q2 = 0.0;  // per pulse
};

Echo echo(const SyntheticSensor& s, double ray_m, double angle, double albedo, double extra_delay_ns,
          double temperature_c) {
  const double td =
      s.tau_ref_ns + s.kappa_ns_per_c * (temperature_c - s.t_ref_c) + 2.0 * ray_m / kLightMPerNs + extra_delay_ns;
  const double c = std::cos(angle);
  const double overlap = 1.0 - std::exp(-(ray_m / s.overlap_m) * (ray_m / s.overlap_m));
  const double e = s.e0 * albedo * c * c * c * c * c * overlap / (ray_m * ray_m);
  const double split = pulse_integral().fraction((s.t0_ns - td) / s.t0_ns);  // share landing in gate 1
  return {e * split, e * (1.0 - split)};
}

}  // namespace

const std::vector<SyntheticMaterial>& table_3_2_materials() {
  static const std::vector<SyntheticMaterial> m = {
      {"white_paper", 6.92 / 6.92}, {"black_cushion", 4.6955 / 6.92}, {"metal_pan", 25.0071 / 6.92},
      {"cloth_bag", 5.1638 / 6.92}, {"styrofoam", 4.8961 / 6.92},     {"white_towel", 5.6881 / 6.92},
      {"cardboard", 4.7981 / 6.92}, {"metal_wrench", 37.125 / 6.92},  {"ic_foam", 0.5699 / 6.92},
  };
  return m;
}

double material_bias_m(double albedo) {
  // (log albedo, bias) from Table 3.2, low-reflectance materials averaged.
  static const std::vector<std::pair<double, double>> pts = {{std::log(0.5699 / 6.92), 0.098339},
                                                             {std::log(4.75 / 6.92), 0.0095},
                                                             {std::log(5.1638 / 6.92), 0.0098},
                                                             {std::log(5.6881 / 6.92), 0.0037},
                                                             {0.0, 0.0007},
                                                             {std::log(25.0071 / 6.92), -0.0150},
                                                             {std::log(37.125 / 6.92), -0.0151}};
  const double x = std::log(albedo);
  if (x <= pts.front().first) return pts.front().second;
  if (x >= pts.back().first) return pts.back().second;
  for (std::size_t i = 1; i < pts.size(); ++i) {
    if (x <= pts[i].first) {
      const double t = (x - pts[i - 1].first) / (pts[i].first - pts[i - 1].first);
      return (1.0 - t) * pts[i - 1].second + t * pts[i].second;
    }
  }
  return 0.0;
}

RailPlan default_rail() {
  RailPlan p;
  for (int i = 1; i <= 40; ++i) p.distances_m.push_back(0.05 * i);
  for (int px = 8; px < 264; px += 4) p.pixels.push_back(px);
  return p;
}

std::vector<double> pixel_sensitivity_ratios(const SyntheticSensor& sensor) { return pixel_constants(sensor).rsen; }
std::vector<double> pixel_pattern_m(const SyntheticSensor& sensor) { return pixel_constants(sensor).pattern_m; }

Charges dark_charges(const SyntheticSensor& s, int pixel, int pulses) {
  const auto consts = pixel_constants(s);
  const double v = s.ambient_per_pulse + s.leak_per_pulse;
  return {pulses * v / consts.rsen[static_cast<std::size_t>(pixel)], pulses * v};
}

Charges expected_charges(const SyntheticSensor& s, double distance_m, double albedo, int pixel, double temperature_c,
                         int pulses) {
  const auto consts = pixel_constants(s);
  const double angle = ray_angle(s, pixel);
  const Echo e = echo(s, distance_m, angle, albedo, 0.0, temperature_c);
  const double v = s.ambient_per_pulse + s.leak_per_pulse;
  return {pulses * (e.q1 + v) / consts.rsen[static_cast<std::size_t>(pixel)], pulses * (e.q2 + v)};
}

namespace {

// The rail's random draws, in one order: the same seed gives the same rail.
struct RailNoise {
  explicit RailNoise(std::uint64_t seed) : rng(seed) {}
  std::mt19937_64 rng;
  std::normal_distribution<double> n01{0.0, 1.0};  // one object: it caches every second draw
  std::uniform_real_distribution<double> u01{0.0, 1.0};
  double normal() { return n01(rng); }
  double uniform() { return u01(rng); }
};

struct Visit {
  double distance;
  std::size_t material;
};

// The defaults for what the plan leaves empty.
RailPlan completed(const RailPlan& in) {
  RailPlan plan = in;
  if (plan.distances_m.empty() || plan.pixels.empty()) {
    const RailPlan d = default_rail();
    if (plan.distances_m.empty()) plan.distances_m = d.distances_m;
    if (plan.pixels.empty()) plan.pixels = d.pixels;
  }
  std::sort(plan.pulses.begin(), plan.pulses.end());
  return plan;
}

// Every distance on every material once per pass, each pass in shuffled order.
std::vector<Visit> shuffled_visits(const RailPlan& plan, RailNoise& noise) {
  std::vector<Visit> visits;
  for (int pass = 0; pass < plan.passes; ++pass) {
    std::vector<Visit> round;
    for (double d : plan.distances_m) {
      for (std::size_t m = 0; m < plan.materials.size(); ++m) round.push_back({d, m});
    }
    std::shuffle(round.begin(), round.end(), noise.rng);
    visits.insert(visits.end(), round.begin(), round.end());
  }
  return visits;
}

// The MCU's reading while the sensor warms, as the wire carries it (0.1 degC).
double mcu_temperature(const SyntheticSensor& s, double t, RailNoise& noise) {
  const double temperature =
      s.ambient_c + (s.t_ref_c - s.ambient_c) * (1.0 - std::exp(-t / s.warmup_s)) + 0.1 * noise.normal();
  return std::round(temperature * 10.0) / 10.0;
}

// The delay of the effects the sensor carries beyond the declared ones [ns].
double undeclared_delay_ns(const SyntheticSensor& s, const PixelConstants& consts, int px, double albedo, double t,
                           double supply) {
  double delay = 0.0;
  if (s.effects.material_bias) delay += 2.0 * material_bias_m(albedo) / kLightMPerNs;
  if (s.effects.pixel_pattern) delay += 2.0 * consts.pattern_m[static_cast<std::size_t>(px)] / kLightMPerNs;
  if (s.effects.time_drift) delay += 2.0 * s.effects.time_drift_m_per_ks * t / 1000.0 / kLightMPerNs;
  if (s.effects.supply_voltage) delay += supply_delay_ns(s, supply);
  return delay;
}

// The read-outs' pulse counts: the firmware's buffer, or the thesis's fixed-discharge
// data (pulses so the fuller capacitor reaches the plan's share of full scale).
std::vector<int> pulse_levels(const SyntheticSensor& s, const RailPlan& plan, const Echo& e, double v_leak,
                              double rsen) {
  if (plan.fixed_discharge <= 0.0) return plan.pulses;
  const double fuller = std::max((e.q1 + v_leak) / rsen, e.q2 + v_leak);
  const double p = plan.fixed_discharge * s.full_scale / std::max(fuller, 1e-9);
  return {static_cast<int>(std::clamp(std::round(p / 10.0) * 10.0, 10.0, 990.0))};
}

// Non-destructive read-outs: one accumulation per capacitor, shot noise as a random walk.
std::vector<Charges> accumulate(const SyntheticSensor& s, const std::vector<int>& levels, const Echo& e, double v_leak,
                                RailNoise& noise) {
  std::vector<Charges> out;
  double acc1 = 0.0, acc2 = 0.0;
  int prev = 0;
  for (int level : levels) {
    const double dp = level - prev;
    prev = level;
    const double m1 = dp * (e.q1 + v_leak), m2 = dp * (e.q2 + v_leak);
    acc1 += m1 + std::sqrt(s.shot_gain * std::max(m1, 0.0)) * noise.normal();
    acc2 += m2 + std::sqrt(s.shot_gain * std::max(m2, 0.0)) * noise.normal();
    out.push_back({acc1, acc2});
  }
  return out;
}

// What the ADC reports for one accumulated charge: the capacitor's transfer
// curve (when the sensor has the effect), ADC noise, the rails, the wire's 0.1.
double adc_reading(const SyntheticSensor& s, double charge, RailNoise& noise) {
  if (s.effects.capacitor_nonlinearity)
    charge *= 1.0 - s.effects.nonlinearity_eta * std::min(charge, s.full_scale) / s.full_scale;
  const double v = std::clamp(charge + s.adc_sd * noise.normal(), -s.full_scale, s.full_scale);
  return s.quantise ? std::round(v * 10.0) / 10.0 : v;  // the wire carries ten times the charge unit as int16
}

struct PixelRead {
  double t = 0.0, temperature = 0.0, supply = 0.0;
  int px = 0;
};

// One pixel's read-outs of one frame, added to `data`.
void read_pixel(const SyntheticSensor& s, const RailPlan& plan, const PixelConstants& consts, const Visit& visit,
                const PixelRead& at, bool supply_col, RailNoise& noise, CalibrationDataset& data) {
  const auto& material = plan.materials[visit.material];
  const double v_leak = s.ambient_per_pulse + s.leak_per_pulse;
  const double angle = ray_angle(s, at.px);
  const double ray_m = visit.distance / std::cos(angle);  // flat target normal to the axis
  const double delay = undeclared_delay_ns(s, consts, at.px, material.albedo, at.t, at.supply);
  // Delay drift with the temperature the MCU reads (declared, 3.3.4) uses the true temperature.
  const Echo e = echo(s, ray_m, angle, material.albedo, delay, at.temperature);
  const double rsen = consts.rsen[static_cast<std::size_t>(at.px)];
  const std::vector<int> levels = pulse_levels(s, plan, e, v_leak, rsen);
  const std::vector<Charges> walk = accumulate(s, levels, e, v_leak, noise);
  for (std::size_t k = 0; k < levels.size(); ++k) {
    Readout r;
    r.a = adc_reading(s, walk[k].a / rsen, noise);
    r.b = adc_reading(s, walk[k].b, noise);
    r.t_s = std::round(at.t * 1000.0) / 1000.0;
    r.pixel = at.px;
    r.pulses = levels[k];
    r.temperature_c = at.temperature;
    const double supply_read = at.supply + 0.005 * noise.normal();  // drawn always: the same seed, the same noise
    if (supply_col) r.extra.push_back(std::round(supply_read * 1000.0) / 1000.0);
    data.add(std::move(r), ray_m, material.name);
  }
}

}  // namespace

CalibrationDataset simulate_rail(const SyntheticSensor& s, const RailPlan& plan_in) {
  const RailPlan plan = completed(plan_in);
  const auto consts = pixel_constants(s);
  RailNoise noise(plan.seed);
  CalibrationDataset data;
  data.source = "synthetic rail";
  data.has_material = plan.materials.size() > 1 || s.effects.material_bias;
  const bool supply_col = s.effects.supply_voltage || s.effects.supply_column;
  if (supply_col) data.extra_names.push_back("supply_v");
  PixelRead at;
  for (const Visit& visit : shuffled_visits(plan, noise)) {
    at.t += plan.move_time_s;
    at.supply = 4.7 + 0.6 * noise.uniform();  // per visit: the bench supply is retuned between visits
    for (int f = 0; f < plan.frames_per_visit; ++f) {
      at.t += plan.frame_period_s;
      at.temperature = mcu_temperature(s, at.t, noise);
      for (int px : plan.pixels) {
        at.px = px;
        read_pixel(s, plan, consts, visit, at, supply_col, noise, data);
      }
    }
  }
  return data;
}

}  // namespace tinyline::tiny_laser_calibration::testing
