// SPDX-License-Identifier: Apache-2.0
#include <sim/fidelity.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include <tiny_laser_calibration/data.hpp>
#include <tiny_laser_calibration/fit.hpp>

#include <sim/yaml_node.hpp>

namespace tinyline::sim {

int select_readout(const SensorSet& set, int pixel) {
  const auto i = static_cast<std::size_t>(pixel);
  for (std::size_t k = set.readouts.size(); k-- > 0;) {
    const auto& r = set.readouts[k];
    const double a = r.a[i], b = r.b[i];
    if (a > 10.0 && a < 230.0 && b > 10.0 && b < 230.0 && a + b > 10.0 + 0.4 * r.pulses / 10.0)
      return static_cast<int>(k);
  }
  return -1;
}

namespace {

namespace tld = tiny_laser_driver;
namespace cal = tiny_laser_calibration;

double mean(const std::vector<double>& v) {
  return v.empty() ? kNaN : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

double sd(const std::vector<double>& v) {
  if (v.size() < 2) return kNaN;
  const double m = mean(v);
  double s = 0.0;
  for (double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / static_cast<double>(v.size() - 1));
}

// The thesis's way to the declared constants (3.3.3): V_le from dark sets,
// R_sen from a uniform exposure with the laser off.
void measure_constants(const SensorParams& params, int pixel, double t_s, std::uint64_t seed, MeasuredConstants& m) {
  SensorParams dark = params;
  dark.environment.ambient_charge_per_pulse = 0.0;  // pitch black
  CalibrationRail rail(dark);
  MeasureOptions off;
  off.laser_on = false;
  const std::vector<int> sched{100, 300, 500, 700, 900};
  double sxy = 0.0, sxx = 0.0;  // V_le = slope of b against pulses in the dark
  for (int k = 0; k < 20; ++k) {
    const SensorSet s = rail.measure(t_s, sched, seed + 1000 + static_cast<std::uint64_t>(k), off);
    for (const auto& r : s.readouts) {
      sxy += r.pulses * r.b[static_cast<std::size_t>(pixel)];
      sxx += static_cast<double>(r.pulses) * r.pulses;
    }
  }
  m.vle_per_pulse = sxy / sxx;  // b = V_le in the dark

  SensorParams lit = params;
  lit.environment.ambient_charge_per_pulse = 0.3;  // a bright, even exposure
  CalibrationRail lamp(lit, RailParams{"white_matte", 1.0, 0.5});
  double sa = 0.0, sb = 0.0;
  const std::vector<int> one{400};
  for (int k = 0; k < 20; ++k) {
    const SensorSet s = lamp.measure(t_s, one, seed + 2000 + static_cast<std::uint64_t>(k), off);
    sa += s.readouts[0].a[static_cast<std::size_t>(pixel)];
    sb += s.readouts[0].b[static_cast<std::size_t>(pixel)];
  }
  m.rsen = sb / sa;  // equal charge in both: b / a = R_sen
}

// Fixed-discharge calibration data at the given fractions: one row per
// distance and discharge, the mean read-out of the sets (the thesis's "one
// data point for each certain distance").
cal::CalibrationDataset collect(const CalibrationRail& tmpl, const std::vector<double>& fractions,
                                const FidelityOptions& o, std::uint64_t seed) {
  CalibrationRail rail = tmpl;
  cal::CalibrationDataset out;
  out.source = "simulated rail";
  std::uint64_t index = seed;
  const auto i = static_cast<std::size_t>(o.pixel);
  double t = o.warm_time_s;
  for (double d = 0.05; d <= 2.0 + 1e-9; d += o.calib_step_m) {
    rail.set_target_distance(d);
    for (double frac : fractions) {
      const std::vector<int> sched{rail.pulses_for_discharge(frac, o.pixel, o.warm_time_s)};
      double sa = 0.0, sb = 0.0, temp = 0.0, range = kNaN;
      int n = 0;
      for (int k = 0; k < o.calib_sets_per_distance; ++k) {
        const SensorSet s = rail.measure(o.warm_time_s, sched, index++);
        range = s.truth[i].range_m;
        if (select_readout(s, o.pixel) != 0) continue;  // valid read-outs only
        sa += s.readouts[0].a[i];
        sb += s.readouts[0].b[i];
        temp += s.temperature_c;
        ++n;
      }
      if (n == 0 || !std::isfinite(range)) continue;
      tld::Readout r;
      r.a = sa / n;
      r.b = sb / n;
      r.pulses = sched[0];
      r.temperature_c = temp / n;
      r.pixel = o.pixel;
      r.t_s = (t += 1.0);  // one "frame" per row
      out.add(r, range);
    }
  }
  return out;
}

FitScore score(const std::string& name, const cal::CalibrationDataset& train, const cal::CalibrationDataset& test,
               int degree, const MeasuredConstants& c, tld::CalibrationModel* fitted = nullptr) {
  cal::DeclaredFitParams fp;
  fp.degree = degree;
  fp.sensitivity_ratio_mode = cal::SensitivityRatioMode::kFixed;
  fp.sensitivity_ratio = c.rsen;
  fp.fit_leakage = false;
  fp.leakage_offset = 0.0;
  fp.leakage_per_pulse = c.vle_per_pulse;
  fp.fit_temperature = false;  // every set is warm
  fp.selection = cal::ReadoutSelection::kAll;
  const cal::DeclaredFitResult fit = cal::fit_declared_model(train, fp);
  if (!fit.status.ok())
    throw std::runtime_error("fidelity: calibration fit '" + name + "' failed: " + fit.status.message);
  std::vector<std::size_t> all(train.size());
  for (std::size_t k = 0; k < all.size(); ++k) all[k] = k;
  const std::vector<double> res = cal::model_residuals(fit.model, train, all);
  std::vector<double> cm;
  for (double r : res)
    if (std::isfinite(r)) cm.push_back(100.0 * r);
  FitScore sc;
  sc.name = name;
  const double mu = mean(cm);
  double v = 0.0;
  for (double r : cm) v += (r - mu) * (r - mu);
  sc.var_cm2 = v / static_cast<double>(std::max<std::size_t>(2, cm.size()) - 1);
  sc.sd_cm = std::sqrt(sc.var_cm2);
  sc.heldout_sd_cm = 100.0 * cal::evaluate_model(fit.model, test, {}, cal::ReadoutSelection::kAll).rmse_m;
  if (fitted) *fitted = fit.model;
  return sc;
}

double model_cm(const tld::CalibrationModel& m, const Readout& ro, std::size_t i, double temperature_c) {
  tld::Readout r;
  r.a = ro.a[i];
  r.b = ro.b[i];
  r.pulses = ro.pulses;
  r.temperature_c = temperature_c;
  r.pixel = static_cast<int>(i);
  r.t_s = ro.t_s;
  return 100.0 * m.distance_m(r);
}

// The calibration fits of 3.2 (scored on held-out sets when o.fits; the
// 40 % poly6 fit into `cal` either way) and the discharge curve at 40 %.
void fit_calibrations(const CalibrationRail& rail, const FidelityOptions& o, std::uint64_t base, FidelityReport& rep) {
  const MeasuredConstants& c = rep.constants;
  tld::CalibrationModel& cal = rep.calibration;
  const auto d40 = collect(rail, {0.4}, o, base + 100000);
  if (o.fits) {
    const auto t40 = collect(rail, {0.4}, o, base + 200000);
    const auto d20 = collect(rail, {0.2}, o, base + 300000);
    const auto t20 = collect(rail, {0.2}, o, base + 400000);
    const auto dm = collect(rail, {0.1, 0.2, 0.4, 0.6, 0.8}, o, base + 500000);
    const auto tm = collect(rail, {0.1, 0.2, 0.4, 0.6, 0.8}, o, base + 600000);
    rep.fits.push_back(score("linear_eq_3_16", d40, t40, 1, c));
    rep.fits.push_back(score("poly3_discharge_40pct", d40, t40, 3, c));
    rep.fits.push_back(score("poly6_discharge_40pct", d40, t40, 6, c, &cal));
    rep.fits.push_back(score("poly6_discharge_20pct", d20, t20, 6, c));
    rep.fits.push_back(score("poly6_multi_discharge", dm, tm, 6, c));
  } else {
    (void)score("poly6_discharge_40pct", d40, d40, 6, c, &cal);
  }
  for (std::size_t k = 0; k < d40.size(); ++k) {
    const auto& r = d40.readouts[k];
    const double vle = c.vle_per_pulse * r.pulses;
    rep.curve.emplace_back(100.0 * d40.distance_m[k], (r.b - vle) / ((r.a * c.rsen - vle) + (r.b - vle)));
  }
}

// Table 3.1: continuous raw mode, read-out selection as the driver does it.
void measure_table31(const SensorParams& sensor, const CalibrationRail& rail, const FidelityOptions& o,
                     std::uint64_t base, FidelityReport& rep) {
  const auto px = static_cast<std::size_t>(o.pixel);
  CalibrationRail r = rail;
  std::uint64_t index = base + 700000;
  for (double truth : {20.5, 50.0, 75.0, 100.0, 125.0}) {
    r.set_target_distance(truth / 100.0);
    DistanceRow row;
    std::vector<double> d, p;
    double range_cm = truth;
    for (int k = 0; k < o.table31_sets; ++k) {
      const SensorSet s = r.measure(o.warm_time_s, sensor.acquisition.raw_pulses, index++);
      range_cm = 100.0 * s.truth[px].range_m;
      const int sel = select_readout(s, o.pixel);
      if (sel < 0) {
        ++row.invalid;
        continue;
      }
      const auto& ro = s.readouts[static_cast<std::size_t>(sel)];
      const double cm = model_cm(rep.calibration, ro, px, s.temperature_c);
      if (!std::isfinite(cm)) {
        ++row.invalid;
        continue;
      }
      d.push_back(cm);
      p.push_back(ro.pulses);
    }
    // Error against the range along the pixel's ray (the centre pixel looks
    // 0.07 deg off axis), reported at the nominal distance.
    row.n = static_cast<int>(d.size());
    row.mean_cm = mean(d) - range_cm + truth;
    row.sd_cm = sd(d);
    row.mean_pulses = mean(p);
    row.truth_cm = truth;
    rep.table31.push_back(row);
  }
}

// Table 3.2: each material at 30 cm, at its 40 % discharge.
void measure_table32(const CalibrationRail& rail, const FidelityOptions& o, std::uint64_t base, FidelityReport& rep) {
  const auto px = static_cast<std::size_t>(o.pixel);
  CalibrationRail r = rail;
  std::uint64_t index = base + 800000;
  for (const char* mat : {"white_paper", "black_cushion", "metal_pan", "cloth_bag", "styrofoam", "white_towel",
                          "cardboard", "metal_wrench", "ic_foam"}) {
    r.set_target_material(mat);
    r.set_target_distance(0.30);
    MaterialRow row;
    row.material = mat;
    row.pulses = r.pulses_for_discharge(0.4, o.pixel, o.warm_time_s);
    const std::vector<int> sched{row.pulses};
    std::vector<double> d, refl;
    double range_cm = 30.0;
    for (int k = 0; k < o.table32_sets; ++k) {
      const SensorSet s = r.measure(o.warm_time_s, sched, index++);
      range_cm = 100.0 * s.truth[px].range_m;
      const auto& ro = s.readouts[0];
      refl.push_back((ro.a[px] + ro.b[px]) / ro.pulses);
      if (select_readout(s, o.pixel) != 0) {
        ++row.invalid;
        continue;
      }
      const double cm = model_cm(rep.calibration, ro, px, s.temperature_c);
      if (!std::isfinite(cm)) {
        ++row.invalid;
        continue;
      }
      d.push_back(cm);
    }
    row.n = static_cast<int>(d.size());
    row.mean_cm = mean(d) - range_cm + 30.0;
    row.sd_cm = sd(d);
    row.reflectance = mean(refl);
    rep.table32.push_back(row);
  }
}

// 3.3.4: distance against the temperature reading while the sensor warms
// up; the least-squares slope, or NaN when flat (unset with too few points).
void temperature_drift(const SensorParams& sensor, const CalibrationRail& rail, const FidelityOptions& o,
                       std::uint64_t base, FidelityReport& rep) {
  const auto px = static_cast<std::size_t>(o.pixel);
  CalibrationRail r = rail;
  r.set_target_distance(0.30);
  const std::vector<int> sched{r.pulses_for_discharge(0.4, o.pixel, o.warm_time_s)};
  std::vector<double> temp, dist;
  std::uint64_t index = base + 900000;
  for (double t = 0.0; t < 5.0 * sensor.thermal.time_constant_s; t += sensor.thermal.time_constant_s / 60.0) {
    const SensorSet s = r.measure(t, sched, index++);
    if (select_readout(s, o.pixel) != 0) continue;
    const double cm =
        model_cm(rep.calibration, s.readouts[0], px, sensor.thermal.reference_c);  // no temperature correction
    if (!std::isfinite(cm)) continue;
    temp.push_back(s.temperature_c);
    dist.push_back(cm);
  }
  if (temp.size() > 3) {  // least-squares slope
    const double mt = mean(temp), md = mean(dist);
    double sxy = 0.0, sxx = 0.0;
    for (std::size_t k = 0; k < temp.size(); ++k) {
      sxy += (temp[k] - mt) * (dist[k] - md);
      sxx += (temp[k] - mt) * (temp[k] - mt);
    }
    rep.temperature_cm_per_c = sxx > 0 ? sxy / sxx : kNaN;
  }
}

}  // namespace

FidelityReport run_fidelity(const SensorParams& sensor, const FidelityOptions& o) {
  FidelityReport rep;
  const std::uint64_t base = o.seed_offset * 1000003ull;
  measure_constants(sensor, o.pixel, o.warm_time_s, base + 1, rep.constants);
  const CalibrationRail rail(sensor);
  fit_calibrations(rail, o, base, rep);
  if (o.table31) measure_table31(sensor, rail, o, base, rep);
  if (o.table32) measure_table32(rail, o, base, rep);
  if (o.temperature) temperature_drift(sensor, rail, o, base, rep);
  return rep;
}

ThesisFigures load_thesis_figures(const std::string& path) {
  const YamlNode root = YamlNode::load_file(path, "thesis figures");
  root.check_keys({"noise_vs_distance_cm", "materials_at_30cm", "calibration_fits_cm"});
  ThesisFigures f;
  for (const auto& e : root.at("noise_vs_distance_cm").items()) {
    e.check_keys({"truth", "mean", "sd"});
    DistanceRow r;
    r.truth_cm = e.get_double("truth");
    r.mean_cm = e.get_double("mean");
    r.sd_cm = e.positive("sd");
    f.table31.push_back(r);
  }
  for (const auto& e : root.at("materials_at_30cm").items()) {
    e.check_keys({"material", "mean_cm", "sd_cm", "reflectance"});
    MaterialRow r;
    r.material = e.get_string("material");
    r.mean_cm = e.get_double("mean_cm");
    r.sd_cm = e.positive("sd_cm");
    r.reflectance = e.positive("reflectance");
    f.table32.push_back(r);
  }
  const YamlNode fits = root.at("calibration_fits_cm");
  for (const auto& k : fits.keys()) {
    const YamlNode e = fits.at(k);
    e.check_keys({"var", "sd"});
    FitScore s;
    s.name = k;
    s.var_cm2 = e.positive("var");
    s.sd_cm = e.positive("sd");
    f.fits.push_back(s);
  }
  return f;
}

namespace {

void fail(FidelityVerdict& v, const std::string& s) { v.failures.push_back(s); }

// Table 3.1: each measured distance's SD within 30 % of the thesis.
void judge_table31(const FidelityReport& r, const ThesisFigures& m, FidelityVerdict& v) {
  for (const auto& meas : m.table31) {
    const auto it = std::find_if(r.table31.begin(), r.table31.end(),
                                 [&](const DistanceRow& d) { return std::abs(d.truth_cm - meas.truth_cm) < 1e-6; });
    if (it == r.table31.end()) {
      fail(v, "Table 3.1: no simulated row at " + std::to_string(meas.truth_cm) + " cm");
      continue;
    }
    const double e = it->sd_cm / meas.sd_cm - 1.0;
    v.worst_sd_ratio_error = std::max(v.worst_sd_ratio_error, std::abs(e));
    if (!(std::abs(e) <= 0.30)) {
      std::ostringstream s;
      s << "Table 3.1 at " << meas.truth_cm << " cm: SD " << it->sd_cm << " cm vs measured " << meas.sd_cm << " cm ("
        << 100.0 * e << " %, goal within 30 %)";
      fail(v, s.str());
    }
  }
}

// Table 3.2: each material's bias within 0.5 cm of the thesis (2 cm for the foam).
void judge_table32(const FidelityReport& r, const ThesisFigures& m, FidelityVerdict& v) {
  for (const auto& meas : m.table32) {
    const auto it = std::find_if(r.table32.begin(), r.table32.end(),
                                 [&](const MaterialRow& x) { return x.material == meas.material; });
    if (it == r.table32.end()) {
      fail(v, "Table 3.2: no simulated row for " + meas.material);
      continue;
    }
    const double e = std::abs((it->mean_cm - 30.0) - (meas.mean_cm - 30.0));
    const bool foam = meas.material == "ic_foam";
    const double goal = foam ? 2.0 : 0.5;
    if (foam)
      v.ic_foam_bias_error_cm = e;
    else
      v.worst_material_bias_cm = std::max(v.worst_material_bias_cm, e);
    if (!(e <= goal) || it->n < 3) {
      std::ostringstream s;
      s << "Table 3.2 " << meas.material << ": bias " << it->mean_cm - 30.0 << " cm vs measured " << meas.mean_cm - 30.0
        << " cm (off by " << e << ", goal " << goal << "; " << it->n << " valid)";
      fail(v, s.str());
    }
  }
}

// Section 3.5: the fits' ordering, the linear fit's size, the multi-discharge penalty.
void judge_fits(const FidelityReport& r, const ThesisFigures& m, FidelityVerdict& v) {
  auto fit = [&](const std::string& n) -> const FitScore* {
    for (const auto& f : r.fits)
      if (f.name == n) return &f;
    return nullptr;
  };
  const FitScore *lin = fit("linear_eq_3_16"), *p3 = fit("poly3_discharge_40pct"), *p6 = fit("poly6_discharge_40pct"),
                 *p20 = fit("poly6_discharge_20pct"), *pm = fit("poly6_multi_discharge");
  const FitScore* lin_m = nullptr;
  for (const auto& f : m.fits)
    if (f.name == "linear_eq_3_16") lin_m = &f;
  if (!lin || !p3 || !p6 || !p20 || !pm || !lin_m) {
    fail(v, "section 3.5: a fit is missing");
    return;
  }
  // Nested least squares on one data set cannot reverse this ordering; the
  // informative parts are the linear fit's size (the curvature of X against
  // distance) and the multi-discharge penalty (the ratio's dependence on the
  // discharge level). 20 % vs 40 % is reported, not judged: the gap is
  // within the simulator's run-to-run spread.
  if (!(lin->var_cm2 > p3->var_cm2 && p3->var_cm2 >= p6->var_cm2))
    fail(v, "section 3.5: fit-degree ordering linear > 3rd > 6th not reproduced");
  const double e = lin->sd_cm / std::sqrt(lin_m->var_cm2) - 1.0;
  if (!(std::abs(e) <= 0.30)) {
    std::ostringstream s;
    s << "section 3.5: linear fit SD " << lin->sd_cm << " cm vs measured " << std::sqrt(lin_m->var_cm2)
      << " cm (goal within 30 %)";
    fail(v, s.str());
  }
  if (!(pm->var_cm2 > 2.0 * p6->var_cm2))
    fail(v, "section 3.5: multi-discharge should fit clearly worse than a single 40 % discharge");
}

}  // namespace

FidelityVerdict judge(const FidelityReport& r, const ThesisFigures& m) {
  FidelityVerdict v;
  judge_table31(r, m, v);
  judge_table32(r, m, v);
  judge_fits(r, m, v);
  return v;
}

}  // namespace tinyline::sim

namespace tinyline::sim {

namespace {

double material_error(const FidelityReport& r, const ThesisFigures& m, const std::string& name) {
  for (const auto& s : r.table32)
    for (const auto& t : m.table32)
      if (s.material == name && t.material == name) {
        const double e = std::abs(s.mean_cm - t.mean_cm);
        return name == "ic_foam" ? 0.25 * e : e;  // IC foam's goal is 2 cm, the others' 0.5 cm
      }
  return kNaN;
}

double sd_error(const FidelityReport& r, const ThesisFigures& m, double truth) {
  for (const auto& s : r.table31)
    for (const auto& t : m.table31)
      if (std::abs(s.truth_cm - truth) < 1e-6 && std::abs(t.truth_cm - truth) < 1e-6)
        return std::abs(s.sd_cm / t.sd_cm - 1.0);
  return kNaN;
}

std::string fmt(double v) {
  std::ostringstream s;
  s.precision(4);
  s << v;
  return s.str();
}

}  // namespace

TuneResult tune_trap(const SensorParams& base, const ThesisFigures& m, const FidelityOptions& o_in) {
  TuneResult t;
  t.what = "trap_delay on Table 3.2";
  t.fit_set = {"white_paper", "black_cushion", "cloth_bag", "metal_pan", "ic_foam"};
  t.held_out = {"styrofoam", "white_towel", "cardboard", "metal_wrench"};
  FidelityOptions o = o_in;
  o.fits = o.table31 = o.temperature = false;
  o.table32 = true;
  double best = kInf;
  std::ostringstream table;
  table << "capacity_per_pulse,release_delay_ns,fit_error_cm,held_out_error_cm\n";
  for (double cap = 0.4; cap <= 1.41; cap += 0.1) {
    for (double delay = 0.9; delay <= 2.01; delay += 0.1) {
      SensorParams p = base;
      std::erase_if(p.effects, [](const EffectSpec& e) { return std::holds_alternative<TrapDelayEffect>(e); });
      p.effects.emplace_back(std::in_place_type<TrapDelayEffect>, cap, delay);
      const FidelityReport r = run_fidelity(p, o);
      double fe = 0.0, he = 0.0;
      for (const auto& n : t.fit_set) fe = std::max(fe, material_error(r, m, n));
      for (const auto& n : t.held_out) he = std::max(he, material_error(r, m, n));
      table << fmt(cap) << "," << fmt(delay) << "," << fmt(fe) << "," << fmt(he) << "\n";
      if (fe < best) {
        best = fe;
        t.best = {{"capacity_per_pulse", cap}, {"release_delay_ns", delay}};
        t.fit_error = fe;
        t.held_out_error = he;
      }
    }
  }
  t.table = table.str();
  return t;
}

TuneResult tune_offset(const SensorParams& base, const ThesisFigures& m, const FidelityOptions& o_in) {
  TuneResult t;
  t.what = "adc_offset_b on the multi-discharge fit";
  t.fit_set = {"poly6_multi_discharge variance"};
  t.held_out = {"linear fit variance (ln ratio)", "Table 3.1 biases (RMS difference, cm)"};
  FidelityOptions o = o_in;
  o.table32 = o.temperature = false;
  o.fits = o.table31 = true;
  auto var_of = [](const std::vector<FitScore>& v, const std::string& n) {
    for (const auto& f : v)
      if (f.name == n) return f.var_cm2;
    return kNaN;
  };
  double best = kInf;
  std::ostringstream table;
  table << "adc_offset_b,multi_var,fit_error,linear_var,table31_bias_rms_cm\n";
  for (double off = 0.0; off >= -2.51; off -= 0.25) {
    SensorParams p = base;
    p.pixel.adc_offset_b = off;
    const FidelityReport r = run_fidelity(p, o);
    const double mv = var_of(r.fits, "poly6_multi_discharge");
    const double fe = std::abs(std::log(mv / var_of(m.fits, "poly6_multi_discharge")));
    const double lin = std::abs(std::log(var_of(r.fits, "linear_eq_3_16") / var_of(m.fits, "linear_eq_3_16")));
    double b2 = 0.0;
    for (std::size_t i = 0; i < r.table31.size() && i < m.table31.size(); ++i) {
      const double d = (r.table31[i].mean_cm - r.table31[i].truth_cm) - (m.table31[i].mean_cm - m.table31[i].truth_cm);
      b2 += d * d;
    }
    const double brms = std::sqrt(b2 / static_cast<double>(std::max<std::size_t>(1, r.table31.size())));
    table << fmt(off) << "," << fmt(mv) << "," << fmt(fe) << "," << fmt(var_of(r.fits, "linear_eq_3_16")) << ","
          << fmt(brms) << "\n";
    if (fe < best) {
      best = fe;
      t.best = {{"adc_offset_b", off}};
      t.fit_error = fe;
      t.held_out_error = brms;
      (void)lin;
    }
  }
  t.table = table.str();
  return t;
}

TuneResult tune_noise(const SensorParams& base, const ThesisFigures& m, const FidelityOptions& o_in) {
  TuneResult t;
  t.what = "noise on Table 3.1 SDs";
  t.fit_set = {"20.5 cm", "75 cm", "125 cm"};
  t.held_out = {"50 cm", "100 cm"};
  FidelityOptions o = o_in;
  o.fits = o.table32 = o.temperature = false;
  o.table31 = true;
  double best = kInf;
  std::ostringstream table;
  table << "read_noise,shot_noise_gain,transfer_noise_per_pulse,fit_error,held_out_error\n";
  for (double rn : {0.1, 0.15, 0.2, 0.3}) {
    for (double g : {1e-4, 2e-4, 4e-4, 8e-4}) {
      for (double tn : {0.035, 0.04, 0.045, 0.05, 0.055}) {
        SensorParams p = base;
        p.pixel.read_noise = rn;
        p.pixel.shot_noise_gain = g;
        p.pixel.transfer_noise_per_pulse = tn;
        const FidelityReport r = run_fidelity(p, o);
        const double fe = std::max({sd_error(r, m, 20.5), sd_error(r, m, 75.0), sd_error(r, m, 125.0)});
        const double he = std::max(sd_error(r, m, 50.0), sd_error(r, m, 100.0));
        table << fmt(rn) << "," << fmt(g) << "," << fmt(tn) << "," << fmt(fe) << "," << fmt(he) << "\n";
        if (fe < best) {
          best = fe;
          t.best = {{"read_noise", rn}, {"shot_noise_gain", g}, {"transfer_noise_per_pulse", tn}};
          t.fit_error = fe;
          t.held_out_error = he;
        }
      }
    }
  }
  t.table = table.str();
  return t;
}

}  // namespace tinyline::sim
