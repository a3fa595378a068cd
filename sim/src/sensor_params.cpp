// SPDX-License-Identifier: Apache-2.0
#include <sim/sensor_params.hpp>

#include <cctype>
#include <cmath>
#include <filesystem>
#include <sstream>

#include <sim/yaml_node.hpp>

namespace tinyline::sim {

namespace detail {
ChargeEffect read_charge_effect(const YamlNode& n);  // charge_effects.cpp
void write_charge_effect(std::ostream& s, const ChargeEffect& e);
}  // namespace detail

namespace {

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

std::vector<int> read_pulses(const YamlNode& n) {
  std::vector<int> out;
  const auto items = n.items();
  if (items.empty() || items.size() > 9) n.fail("expected 1 to 9 pulse counts");
  for (const auto& e : items) {
    const int p = e.as_int();
    if (p < 10 || p > 990 || p % 10 != 0)
      e.fail("pulse count must be a multiple of 10 in [10, 990] (got " + std::to_string(p) + ")");
    if (!out.empty() && p <= out.back()) e.fail("pulse counts must increase");
    out.push_back(p);
  }
  return out;
}

EffectSpec read_effect(const YamlNode& n) {
  n.require_map();
  const std::string type = n.get_string("type");
  if (type == "trap_delay") {
    n.check_keys({"type", "capacity_per_pulse", "release_delay_ns"});
    TrapDelayEffect e;
    e.capacity_per_pulse = n.non_negative("capacity_per_pulse", e.capacity_per_pulse);
    e.release_delay_ns = n.in_range("release_delay_ns", e.release_delay_ns, -20.0, 20.0);
    return e;
  }
  if (type == "material_bias") {
    n.check_keys({"type", "path_mm"});
    MaterialBiasEffect e;
    const YamlNode m = n.at("path_mm");
    m.require_map();
    for (const auto& k : m.keys()) {
      const double v = m.at(k).as_double();
      if (std::abs(v) > 2000.0) m.at(k).fail("extra path must be within +-2000 mm");
      e.path_mm[k] = v;
    }
    return e;
  }
  if (type == "fixed_pattern") {
    n.check_keys({"type", "sigma_ps", "ramp_ps", "seed"});
    FixedPatternEffect e;
    e.sigma_ps = n.in_range("sigma_ps", e.sigma_ps, 0.0, 10000.0);
    e.ramp_ps = n.in_range("ramp_ps", e.ramp_ps, -10000.0, 10000.0);
    e.seed = static_cast<std::uint64_t>(n.in_range("seed", static_cast<double>(e.seed), 0.0, 4.0e9));
    return e;
  }
  if (type == "range_walk") {
    n.check_keys({"type", "ns_per_decade", "reference_charge_per_pulse", "max_ns"});
    RangeWalkEffect e;
    e.ns_per_decade = n.in_range("ns_per_decade", e.ns_per_decade, -10.0, 10.0);
    e.reference_charge_per_pulse = n.positive("reference_charge_per_pulse", e.reference_charge_per_pulse);
    e.max_ns = n.positive("max_ns", e.max_ns);
    return e;
  }
  if (type == "time_drift") {
    n.check_keys({"type", "ns_per_hour", "sine_amplitude_ns", "sine_period_s"});
    TimeDriftEffect e;
    e.ns_per_hour = n.in_range("ns_per_hour", e.ns_per_hour, -100.0, 100.0);
    e.sine_amplitude_ns = n.in_range("sine_amplitude_ns", e.sine_amplitude_ns, 0.0, 100.0);
    e.sine_period_s = n.positive("sine_period_s", e.sine_period_s);
    return e;
  }
  if (type == "covariate") {
    n.check_keys({"type", "name", "mean", "amplitude", "period_s", "random_walk_per_sqrt_s", "ns_per_unit"});
    CovariateEffect e;
    e.name = n.get_string("name", e.name);
    if (e.name.empty()) n.at("name").fail("must not be empty");
    for (char c : e.name)
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_'))
        n.at("name").fail("use letters, digits and '_' only (it becomes a CSV column)");
    e.mean = n.get_double("mean", e.mean);
    e.amplitude = n.non_negative("amplitude", e.amplitude);
    e.period_s = n.positive("period_s", e.period_s);
    e.random_walk_per_sqrt_s = n.non_negative("random_walk_per_sqrt_s", e.random_walk_per_sqrt_s);
    e.ns_per_unit = n.in_range("ns_per_unit", e.ns_per_unit, -100.0, 100.0);
    return e;
  }
  if (type == "charge") return detail::read_charge_effect(n);
  if (type == "temperature_lag") {
    n.check_keys({"type", "time_constant_s"});
    TemperatureLagEffect e;
    e.time_constant_s = n.positive("time_constant_s", e.time_constant_s);
    return e;
  }
  std::string known;
  for (const auto& t : effect_types()) known += (known.empty() ? "" : ", ") + t;
  n.at("type").fail("unknown effect type '" + type + "' (known: " + known + ")");
}

void read_lens(const YamlNode* l, LensParams& x) {
  l->check_keys({"focal_mm", "sensor_length_mm", "pixels", "dark_pixels", "subrays_per_pixel", "psf_sigma_px",
                 "halo_fraction", "halo_length_px", "vignetting_cos_power", "pixel_height_mm"});
  x.focal_mm = l->in_range("focal_mm", x.focal_mm, 0.5, 100.0);
  x.sensor_length_mm = l->in_range("sensor_length_mm", x.sensor_length_mm, 0.1, 100.0);
  x.pixels = static_cast<int>(l->in_range("pixels", x.pixels, 3, 4096));
  x.dark_pixels = static_cast<int>(l->in_range("dark_pixels", x.dark_pixels, 0, 64));
  x.subrays_per_pixel = static_cast<int>(l->in_range("subrays_per_pixel", x.subrays_per_pixel, 1, 16));
  x.psf_sigma_px = l->in_range("psf_sigma_px", x.psf_sigma_px, 0.0, 20.0);
  x.halo_fraction = l->in_range("halo_fraction", x.halo_fraction, 0.0, 0.5);
  x.halo_length_px = l->in_range("halo_length_px", x.halo_length_px, 0.1, 200.0);
  x.vignetting_cos_power = l->in_range("vignetting_cos_power", x.vignetting_cos_power, 0.0, 8.0);
  x.pixel_height_mm = l->in_range("pixel_height_mm", x.pixel_height_mm, 0.001, 20.0);
}

void read_emitter(const YamlNode* e, EmitterParams& x) {
  e->check_keys({"baseline_m", "fan_half_angle_deg", "fan_edge_deg", "sheet_thickness_mm", "sheet_divergence_deg",
                 "pulse_width_ns", "pulse_rise_exponent", "pulse_fall_exponent", "diffusion_tail_ns", "pulse_rate_hz",
                 "charge_per_pulse_1m"});
  x.baseline_m = e->in_range("baseline_m", x.baseline_m, -0.2, 0.2);
  x.fan_half_angle_deg = e->in_range("fan_half_angle_deg", x.fan_half_angle_deg, 0.5, 89.0);
  x.fan_edge_deg = e->in_range("fan_edge_deg", x.fan_edge_deg, 0.0, 30.0);
  x.sheet_thickness_mm = e->in_range("sheet_thickness_mm", x.sheet_thickness_mm, 0.0, 100.0);
  x.sheet_divergence_deg = e->in_range("sheet_divergence_deg", x.sheet_divergence_deg, 0.0, 45.0);
  x.pulse_width_ns = e->in_range("pulse_width_ns", x.pulse_width_ns, 1.0, 1000.0);
  x.pulse_rise_exponent = e->in_range("pulse_rise_exponent", x.pulse_rise_exponent, 0.0, 10.0);
  x.pulse_fall_exponent = e->in_range("pulse_fall_exponent", x.pulse_fall_exponent, 0.0, 10.0);
  x.diffusion_tail_ns = e->in_range("diffusion_tail_ns", x.diffusion_tail_ns, 0.0, 100.0);
  x.pulse_rate_hz = e->in_range("pulse_rate_hz", x.pulse_rate_hz, 1.0, 1.0e7);
  x.charge_per_pulse_1m = e->non_negative("charge_per_pulse_1m", x.charge_per_pulse_1m);
}

void read_pixel(const YamlNode* q, PixelParams& x) {
  q->check_keys({"gate_split_ns", "sensitivity_ratio", "sensitivity_ratio_sd", "leakage_per_ms", "leakage_sd",
                 "prnu_sd", "full_scale", "knee", "nonlinearity", "read_noise", "shot_noise_gain",
                 "transfer_noise_per_pulse", "adc_offset_a", "adc_offset_b", "adc_lsb", "adc_max"});
  x.gate_split_ns = q->in_range("gate_split_ns", x.gate_split_ns, -1000.0, 1000.0);
  x.sensitivity_ratio = q->in_range("sensitivity_ratio", x.sensitivity_ratio, 0.1, 10.0);
  x.sensitivity_ratio_sd = q->in_range("sensitivity_ratio_sd", x.sensitivity_ratio_sd, 0.0, 0.5);
  x.leakage_per_ms = q->non_negative("leakage_per_ms", x.leakage_per_ms);
  x.leakage_sd = q->in_range("leakage_sd", x.leakage_sd, 0.0, 1.0);
  x.prnu_sd = q->in_range("prnu_sd", x.prnu_sd, 0.0, 0.5);
  x.full_scale = q->positive("full_scale", x.full_scale);
  x.knee = q->positive("knee", x.knee);
  x.nonlinearity = q->in_range("nonlinearity", x.nonlinearity, 0.0, 0.5);
  x.read_noise = q->non_negative("read_noise", x.read_noise);
  x.shot_noise_gain = q->non_negative("shot_noise_gain", x.shot_noise_gain);
  x.transfer_noise_per_pulse = q->non_negative("transfer_noise_per_pulse", x.transfer_noise_per_pulse);
  x.adc_offset_a = q->in_range("adc_offset_a", x.adc_offset_a, -50.0, 50.0);
  x.adc_offset_b = q->in_range("adc_offset_b", x.adc_offset_b, -50.0, 50.0);
  x.adc_lsb = q->positive("adc_lsb", x.adc_lsb);
  x.adc_max = q->positive("adc_max", x.adc_max);
}

void read_firmware(const YamlNode& f, FirmwareParams& x) {
  f.check_keys({"profile", "tick_s", "cycle_ticks", "sensitivity_ratio", "compensated_pixel",
                "compensated_pixel_factor", "saturation_charge"});
  if (auto pr = f.find("profile")) {
    const auto profile = firmware_profile_from_string(pr->as_string());
    if (!profile) pr->fail("unknown firmware profile '" + pr->as_string() + "' (known: thesis_raw, published)");
    x.profile = *profile;
  }
  x.tick_s = f.in_range("tick_s", x.tick_s, 1e-6, 1.0);
  x.cycle_ticks = static_cast<int>(f.in_range("cycle_ticks", x.cycle_ticks, 10, 1000000));
  x.sensitivity_ratio = f.in_range("sensitivity_ratio", x.sensitivity_ratio, 0.1, 10.0);
  x.compensated_pixel = static_cast<int>(f.in_range("compensated_pixel", x.compensated_pixel, -1, 4095));
  x.compensated_pixel_factor = f.in_range("compensated_pixel_factor", x.compensated_pixel_factor, 0.1, 10.0);
  x.saturation_charge = f.positive("saturation_charge", x.saturation_charge);
}

}  // namespace

const char* to_string(FirmwareProfile p) { return p == FirmwareProfile::kPublished ? "published" : "thesis_raw"; }

std::optional<FirmwareProfile> firmware_profile_from_string(std::string_view s) {
  if (s == "thesis_raw") return FirmwareProfile::kThesisRaw;
  if (s == "published") return FirmwareProfile::kPublished;
  return std::nullopt;
}

const char* effect_type(const EffectSpec& e) {
  return std::visit(Overloaded{[](const TrapDelayEffect&) { return "trap_delay"; },
                               [](const MaterialBiasEffect&) { return "material_bias"; },
                               [](const FixedPatternEffect&) { return "fixed_pattern"; },
                               [](const RangeWalkEffect&) { return "range_walk"; },
                               [](const TimeDriftEffect&) { return "time_drift"; },
                               [](const CovariateEffect&) { return "covariate"; },
                               [](const TemperatureLagEffect&) { return "temperature_lag"; },
                               [](const ChargeEffect&) { return "charge"; }},
                    e);
}

std::vector<std::string> effect_types() {
  return {"trap_delay", "material_bias", "fixed_pattern",   "range_walk",
          "time_drift", "covariate",     "temperature_lag", "charge"};
}

void apply_sensor_params(const YamlNode& n, SensorParams& p) {
  n.check_keys({"base", "name", "seed", "lens", "emitter", "pixel", "thermal", "acquisition", "environment", "firmware",
                "effects"});
  p.name = n.get_string("name", p.name);
  if (auto s = n.find("seed")) {
    const double v = s->as_double();
    if (v < 0 || v > 1.8e19 || v != std::floor(v)) s->fail("seed must be a non-negative integer");
    p.seed = static_cast<std::uint64_t>(v);
  }
  if (auto l = n.find("lens")) read_lens(&*l, p.lens);
  if (auto e = n.find("emitter")) read_emitter(&*e, p.emitter);
  if (auto q = n.find("pixel")) read_pixel(&*q, p.pixel);
  if (auto t = n.find("thermal")) {
    t->check_keys({"ambient_c", "warm_c", "time_constant_s", "reference_c", "delay_drift_ns_per_c", "reading_noise_c"});
    auto& x = p.thermal;
    x.ambient_c = t->in_range("ambient_c", x.ambient_c, -40.0, 100.0);
    x.warm_c = t->in_range("warm_c", x.warm_c, -40.0, 100.0);
    x.time_constant_s = t->positive("time_constant_s", x.time_constant_s);
    x.reference_c = t->in_range("reference_c", x.reference_c, -40.0, 100.0);
    x.delay_drift_ns_per_c = t->in_range("delay_drift_ns_per_c", x.delay_drift_ns_per_c, -5.0, 5.0);
    x.reading_noise_c = t->in_range("reading_noise_c", x.reading_noise_c, 0.0, 5.0);
  }
  if (auto a = n.find("acquisition")) {
    a->check_keys({"raw_pulses", "distance_pulses"});
    if (auto r = a->find("raw_pulses")) p.acquisition.raw_pulses = read_pulses(*r);
    if (auto d = a->find("distance_pulses")) p.acquisition.distance_pulses = read_pulses(*d);
  }
  if (auto e = n.find("environment")) {
    e->check_keys({"ambient_charge_per_pulse"});
    p.environment.ambient_charge_per_pulse =
        e->non_negative("ambient_charge_per_pulse", p.environment.ambient_charge_per_pulse);
  }
  if (auto f = n.find("firmware")) read_firmware(*f, p.firmware);
  if (auto e = n.find("effects")) {
    p.effects.clear();  // a file's list replaces its base's list
    for (const auto& item : e->items()) p.effects.push_back(read_effect(item));
  }
  if (const common::Status why = p.validate(); !why.ok()) n.fail(why.message);
}

SensorParams load_sensor_params(const std::string& path) {
  const YamlNode root = YamlNode::load_file(path, "sensor file");
  root.require_map();
  SensorParams p;
  if (auto b = root.find("base")) {
    std::filesystem::path base = b->as_string();
    if (base.is_relative()) base = std::filesystem::path(path).parent_path() / base;
    if (std::filesystem::weakly_canonical(base) == std::filesystem::weakly_canonical(path))
      b->fail("a sensor file cannot be its own base");
    try {
      p = load_sensor_params(base.string());
    } catch (const ConfigError& e) {
      if (e.file() == base.string() && e.line() == 0) b->fail("cannot read base file '" + base.string() + "'");
      throw;
    }
  }
  apply_sensor_params(root, p);
  return p;
}

common::Status SensorParams::validate() const {
  if (lens.pixels <= 2 * lens.dark_pixels)
    return common::Status::invalid("lens.pixels must exceed twice lens.dark_pixels");
  if (pixel.knee > pixel.full_scale) return common::Status::invalid("pixel.knee must not exceed pixel.full_scale");
  if (pixel.adc_max < pixel.full_scale)
    return common::Status::invalid("pixel.adc_max must be at least pixel.full_scale");
  if (pixel.adc_max * 10.0 > 32767.0) return common::Status::invalid("pixel.adc_max * 10 must fit the wire's int16");
  if (thermal.warm_c < thermal.ambient_c - 50.0)
    return common::Status::invalid("thermal.warm_c is implausibly below thermal.ambient_c");
  if (thermal.warm_c >= 65.5 || thermal.ambient_c >= 65.5)
    return common::Status::invalid("temperatures must stay below 65.5 degC (the wire packs 0.1 degC * 100)");
  if (firmware.compensated_pixel >= lens.pixels)
    return common::Status::invalid("firmware.compensated_pixel must be a pixel (or -1: none)");
  return common::Status{};
}

namespace {
std::string int_list(const std::vector<int>& v) {
  std::string out = "[";
  for (std::size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + std::to_string(v[i]);
  return out + "]";
}

// lens: and emitter:
void write_optics(std::ostream& s, const SensorParams& p) {
  const auto& l = p.lens;
  s << "lens:\n  focal_mm: " << l.focal_mm << "\n  sensor_length_mm: " << l.sensor_length_mm
    << "\n  pixels: " << l.pixels << "\n  dark_pixels: " << l.dark_pixels
    << "\n  subrays_per_pixel: " << l.subrays_per_pixel << "\n  psf_sigma_px: " << l.psf_sigma_px
    << "\n  halo_fraction: " << l.halo_fraction << "\n  halo_length_px: " << l.halo_length_px
    << "\n  vignetting_cos_power: " << l.vignetting_cos_power << "\n  pixel_height_mm: " << l.pixel_height_mm << "\n";
  const auto& e = p.emitter;
  s << "emitter:\n  baseline_m: " << e.baseline_m << "\n  fan_half_angle_deg: " << e.fan_half_angle_deg
    << "\n  fan_edge_deg: " << e.fan_edge_deg << "\n  sheet_thickness_mm: " << e.sheet_thickness_mm
    << "\n  sheet_divergence_deg: " << e.sheet_divergence_deg << "\n  pulse_width_ns: " << e.pulse_width_ns
    << "\n  pulse_rise_exponent: " << e.pulse_rise_exponent << "\n  pulse_fall_exponent: " << e.pulse_fall_exponent
    << "\n  diffusion_tail_ns: " << e.diffusion_tail_ns << "\n  pulse_rate_hz: " << e.pulse_rate_hz
    << "\n  charge_per_pulse_1m: " << e.charge_per_pulse_1m << "\n";
}

// pixel:, thermal:, acquisition:, environment:, firmware:
void write_electronics(std::ostream& s, const SensorParams& p) {
  const auto& q = p.pixel;
  s << "pixel:\n  gate_split_ns: " << q.gate_split_ns << "\n  sensitivity_ratio: " << q.sensitivity_ratio
    << "\n  sensitivity_ratio_sd: " << q.sensitivity_ratio_sd << "\n  leakage_per_ms: " << q.leakage_per_ms
    << "\n  leakage_sd: " << q.leakage_sd << "\n  prnu_sd: " << q.prnu_sd << "\n  full_scale: " << q.full_scale
    << "\n  knee: " << q.knee << "\n  nonlinearity: " << q.nonlinearity << "\n  read_noise: " << q.read_noise
    << "\n  shot_noise_gain: " << q.shot_noise_gain << "\n  transfer_noise_per_pulse: " << q.transfer_noise_per_pulse
    << "\n  adc_offset_a: " << q.adc_offset_a << "\n  adc_offset_b: " << q.adc_offset_b << "\n  adc_lsb: " << q.adc_lsb
    << "\n  adc_max: " << q.adc_max << "\n";
  const auto& t = p.thermal;
  s << "thermal:\n  ambient_c: " << t.ambient_c << "\n  warm_c: " << t.warm_c
    << "\n  time_constant_s: " << t.time_constant_s << "\n  reference_c: " << t.reference_c
    << "\n  delay_drift_ns_per_c: " << t.delay_drift_ns_per_c << "\n  reading_noise_c: " << t.reading_noise_c << "\n";
  s << "acquisition:\n  raw_pulses: " << int_list(p.acquisition.raw_pulses)
    << "\n  distance_pulses: " << int_list(p.acquisition.distance_pulses) << "\n";
  s << "environment:\n  ambient_charge_per_pulse: " << p.environment.ambient_charge_per_pulse << "\n";
  const auto& f = p.firmware;
  s << "firmware:\n  profile: " << to_string(f.profile) << "\n  tick_s: " << f.tick_s
    << "\n  cycle_ticks: " << f.cycle_ticks << "\n  sensitivity_ratio: " << f.sensitivity_ratio
    << "\n  compensated_pixel: " << f.compensated_pixel
    << "\n  compensated_pixel_factor: " << f.compensated_pixel_factor
    << "\n  saturation_charge: " << f.saturation_charge << "\n";
}

// One item of effects:, its type's fields.
void write_effect(std::ostream& s, const EffectSpec& fx) {
  s << "  - type: " << effect_type(fx) << "\n";
  std::visit(
      Overloaded{[&](const TrapDelayEffect& x) {
                   s << "    capacity_per_pulse: " << x.capacity_per_pulse
                     << "\n    release_delay_ns: " << x.release_delay_ns << "\n";
                 },
                 [&](const MaterialBiasEffect& x) {
                   s << "    path_mm: {";
                   bool first = true;
                   for (const auto& [k, v] : x.path_mm) {
                     s << (first ? "" : ", ") << k << ": " << v;
                     first = false;
                   }
                   s << "}\n";
                 },
                 [&](const FixedPatternEffect& x) {
                   s << "    sigma_ps: " << x.sigma_ps << "\n    ramp_ps: " << x.ramp_ps << "\n    seed: " << x.seed
                     << "\n";
                 },
                 [&](const RangeWalkEffect& x) {
                   s << "    ns_per_decade: " << x.ns_per_decade
                     << "\n    reference_charge_per_pulse: " << x.reference_charge_per_pulse
                     << "\n    max_ns: " << x.max_ns << "\n";
                 },
                 [&](const TimeDriftEffect& x) {
                   s << "    ns_per_hour: " << x.ns_per_hour << "\n    sine_amplitude_ns: " << x.sine_amplitude_ns
                     << "\n    sine_period_s: " << x.sine_period_s << "\n";
                 },
                 [&](const CovariateEffect& x) {
                   s << "    name: " << x.name << "\n    mean: " << x.mean << "\n    amplitude: " << x.amplitude
                     << "\n    period_s: " << x.period_s << "\n    random_walk_per_sqrt_s: " << x.random_walk_per_sqrt_s
                     << "\n    ns_per_unit: " << x.ns_per_unit << "\n";
                 },
                 [&](const TemperatureLagEffect& x) { s << "    time_constant_s: " << x.time_constant_s << "\n"; },
                 [&](const ChargeEffect& x) { detail::write_charge_effect(s, x); }},
      fx);
}
}  // namespace

std::string to_yaml(const SensorParams& p) {
  std::ostringstream s;
  s.precision(10);
  s << "name: " << p.name << "\nseed: " << p.seed << "\n";
  write_optics(s, p);
  write_electronics(s, p);
  s << "effects:";
  if (p.effects.empty()) s << " []";
  s << "\n";
  for (const auto& fx : p.effects) write_effect(s, fx);
  return s.str();
}

}  // namespace tinyline::sim
