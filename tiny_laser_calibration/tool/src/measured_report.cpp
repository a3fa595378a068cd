// SPDX-License-Identifier: Apache-2.0
// `tinyline calib measured`: the calibration loop on every real measurement
// the project holds (measured.hpp), as a report.
#include <cmath>
#include <filesystem>
#include <ostream>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tinyline/common/files.hpp>

#include <tiny_laser_calibration/data.hpp>
#include <tiny_laser_calibration/discovery.hpp>
#include <tiny_laser_driver/calibration.hpp>
#include <tiny_laser_calibration/measured.hpp>

#include "calib_tool_internal.hpp"

namespace tinyline::tiny_laser_calibration::tool {

namespace {

std::string hypothesis_table(const std::vector<EffectHypothesis>& hs, int best, const char* error_name) {
  std::string md = fmt::format(
      "| effect | form | parameters | {} | with the size penalty | in-sample RMSE | fitted, in physical units |\n"
      "|---|---|---|---|---|---|---|\n",
      error_name);
  for (std::size_t i = 0; i < hs.size(); ++i) {
    const auto& h = hs[i];
    md += fmt::format("| {}{} | `{}` | {} | {:.2f} cm | {:.2f} cm | {:.2f} cm | {} |\n",
                      static_cast<int>(i) == best ? "**chosen:** " : "", h.effect, h.form, h.n_params, h.loo_rmse_cm,
                      h.score_cm, h.in_sample_rmse_cm, h.reading);
  }
  return md + "\n";
}

std::string materials_section(const MeasuredData& d, const MaterialAnalysis& a) {
  std::string md = "## Table 3.2: bias per material against the reflectance the sensor reports\n\n";
  md += fmt::format(
      "Calibrated on white paper (its own bias {:+.2f} cm is the anchor every hypothesis passes through); "
      "q = reflectance / white paper's. Leave-one-material-out over the {} other surfaces.\n\n",
      a.white_bias_cm, d.table32.size() - 1);
  md += fmt::format("Before (the declared model: every surface reads like white paper): **{:.2f} cm** RMS.\n\n",
                    a.before_rmse_cm);
  md +=
      "Nested families, each with its physical reading; the choice ranks the leave-one-out RMSE times "
      "sqrt(n / (n - parameters)) (n = 8 surfaces predicted), so a larger form has to predict better by more "
      "than its size.\n\n";
  md += hypothesis_table(a.hypotheses, a.best, "leave-one-out RMSE");
  if (a.best >= 0) {
    const auto& h = a.hypotheses[static_cast<std::size_t>(a.best)];
    md += fmt::format("After (chosen: `{}`, leave-one-material-out): **{:.2f} cm** RMS, from {:.2f} cm. {}: {}.\n\n",
                      h.form, h.loo_rmse_cm, a.before_rmse_cm, h.effect, h.reading);
    md +=
        fmt::format("What drives the choice (each surface left out of the whole ranking): {}. {}\n\n",
                    fmt::join(a.choice_without, "; "),
                    a.drivers.empty() ? "No single surface changes it."
                                      : fmt::format("Without {} another form is chosen.", fmt::join(a.drivers, ", ")));
    md += "| material | reflectance | bias [cm] | left over, leave-one-out [cm] |\n|---|---|---|---|\n";
    for (std::size_t i = 0; i < d.table32.size(); ++i) {
      const auto& m = d.table32[i];
      const double r = h.loo_residual_cm[i];
      md += fmt::format("| {} | {} | {:+.2f} | {} |\n", m.name, m.reflectance, m.mean_cm - 30.0,
                        std::isfinite(r) ? fmt::format("{:+.2f}", r) : "(anchor)");
    }
    md += "\n";
    if (a.unexplained.empty()) {
      md += "Nothing is left beyond three standard errors of a material's mean.\n\n";
    } else {
      md += "Left unexplained (beyond three standard errors of the mean, or 0.3 cm):\n\n";
      for (const auto& u : a.unexplained) md += "- " + u + "\n";
      md += "\n";
    }
  }
  return md;
}

std::string distances_section(const MeasuredData& d, const DistanceAnalysis& a) {
  std::string md = "## Table 3.1: bias and spread against distance (white paper)\n\n";
  md += fmt::format(
      "Before (the published calibration): **{:.2f} cm** RMS bias over the {} distances. "
      "Leave-one-distance-out:\n\n",
      a.before_rmse_cm, d.table31.size());
  md += hypothesis_table(a.hypotheses, a.best, "leave-one-out RMSE");
  md += fmt::format("Spread: {}.\n\n", a.sd_reading);
  return md;
}

std::string fits_section(const FitsAnalysis& a) {
  std::string md = "## Section 3.5: what the published fits say\n\n";
  for (const auto& r : a.readings) md += "- " + r + "\n";
  return md + "\n";
}

std::string curves_section(const std::vector<CurveAnalysis>& cs) {
  std::string md = "## The five real sensors' factory curves\n\n";
  md +=
      "Each curve held against the declared physical model where it reads the thesis's calibration range "
      "(5-200 cm), 401 points evenly in k = b / (a + b); Rsen kept within a factor 2 of 1 and the pulse power "
      "positive. RMS residual held out by blocks of distance (five contiguous stretches of k, each predicted from "
      "a fit on the other four; the end blocks are extrapolations), in-sample in brackets:\n\n";
  md +=
      "| sensor | k | distance [cm] | Eq. 3.16 (before) | + gain on A | + pulse shape | chosen (held out) | fitted, "
      "chosen | delay drift |\n"
      "|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& c : cs) {
    std::string cells;
    for (const auto& m : c.models) cells += fmt::format("{:.2f} cm ({:.2f}) | ", m.loo_rmse_cm, m.in_sample_rmse_cm);
    const auto& b = c.models[static_cast<std::size_t>(std::max(c.best, 0))];
    md += fmt::format("| {} | {:.3f}-{:.3f} | {:.0f}-{:.0f} | {}{} | {} | {:.1f} ps/degC |\n", c.sensor, c.k_min,
                      c.k_max, c.l_min_cm, c.l_max_cm, cells, b.effect, b.reading, c.delay_drift_ps_per_c);
  }
  return md + "\n";
}

Json::Value numbers_json(const std::vector<double>& v) {
  Json::Value a(Json::arrayValue);
  for (double x : v) a.append(json_number(x));
  return a;
}

Json::Value hypotheses_json(const std::vector<EffectHypothesis>& hs) {
  Json::Value a(Json::arrayValue);
  for (const auto& h : hs) {
    Json::Value j;
    j["effect"] = h.effect;
    j["form"] = h.form;
    j["n_params"] = h.n_params;
    j["params"] = numbers_json(h.params);
    j["loo_rmse_cm"] = json_number(h.loo_rmse_cm);
    j["score_cm"] = json_number(h.score_cm);
    j["in_sample_rmse_cm"] = json_number(h.in_sample_rmse_cm);
    j["loo_residual_cm"] = numbers_json(h.loo_residual_cm);
    j["bound"] = h.bound;
    a.append(j);
  }
  return a;
}

Json::Value curve_json(const CurveAnalysis& c) {
  Json::Value j;
  j["sensor"] = c.sensor;
  j["k_min"] = json_number(c.k_min);
  j["k_max"] = json_number(c.k_max);
  j["best"] = c.best;
  for (const auto& m : c.models) {
    j["heldout_rmse_cm"].append(json_number(m.loo_rmse_cm));
    j["in_sample_rmse_cm"].append(json_number(m.in_sample_rmse_cm));
    j["bound"].append(m.bound);
  }
  return j;
}

std::string report_json(const MaterialAnalysis& m, const DistanceAnalysis& dist, const FitsAnalysis& f,
                        const std::vector<CurveAnalysis>& cs) {
  Json::Value j;
  auto& t32 = j["table32"];
  t32["before_rmse_cm"] = json_number(m.before_rmse_cm);
  t32["best"] = m.best;
  t32["drivers"] = Json::Value(Json::arrayValue);
  for (const auto& d : m.drivers) t32["drivers"].append(d);
  t32["hypotheses"] = hypotheses_json(m.hypotheses);
  auto& t31 = j["table31"];
  t31["before_rmse_cm"] = json_number(dist.before_rmse_cm);
  t31["best"] = dist.best;
  t31["sd_log_slope"] = json_number(dist.sd_log_slope);
  t31["hypotheses"] = hypotheses_json(dist.hypotheses);
  j["section35"]["noise_exponent"] = json_number(f.noise_exponent);
  j["section35"]["multi_shot_prediction_cm2"] = json_number(f.multi_shot_prediction_cm2);
  j["curves"] = Json::Value(Json::arrayValue);
  for (const auto& c : cs) j["curves"].append(curve_json(c));
  return json_text(j);
}

// The data the plot script draws (measured_*.csv).
void write_plot_data(const std::string& dir, const MeasuredData& d, const MaterialAnalysis& m,
                     const std::vector<CurveAnalysis>& cs) {
  namespace fs = std::filesystem;
  {
    files::AtomicStream out((fs::path(dir) / "measured_materials.csv").string());
    out << "material,reflectance,bias_cm,sd_cm,loo_residual_cm\n";
    const auto* h = m.best >= 0 ? &m.hypotheses[static_cast<std::size_t>(m.best)] : nullptr;
    for (std::size_t i = 0; i < d.table32.size(); ++i) {
      const auto& t = d.table32[i];
      out << fmt::format("{},{},{},{},{}\n", t.name, t.reflectance, t.mean_cm - 30.0, t.sd_cm,
                         h && std::isfinite(h->loo_residual_cm[i]) ? fmt::format("{}", h->loo_residual_cm[i]) : "");
    }
    out.commit();
  }
  files::AtomicStream out((fs::path(dir) / "measured_curves.csv").string());
  out << "sensor,k,l_cm,residual_declared_cm,residual_best_cm\n";
  for (const auto& c : cs) {
    for (std::size_t i = 0; i < c.k.size(); ++i) {
      out << fmt::format("{},{},{},{},{}\n", c.sensor, c.k[i], c.l_cm[i], c.models[0].loo_residual_cm[i],
                         c.best_residual_cm[i]);
    }
  }
  out.commit();
}

// Adds the chosen Table 3.2 walk to a calibration and writes it where the driver loads it from.
void apply_walk(const MaterialAnalysis& mat, const std::string& in, const std::string& out_path, std::ostream& out) {
  auto model = tiny_laser_driver::CalibrationModel::load(in);
  if (model.impl().amplitude_reference.empty())
    throw std::runtime_error(
        fmt::format("{}: no amplitude_reference, so the driver cannot compute the albedo the walk term needs (fit the "
                    "calibration with `tinyline calib fit` on a rail)",
                    in));
  const auto term = material_walk_term(mat);
  model.impl().terms.push_back(term);
  model.impl().resolve();
  model.save(out_path);
  out << fmt::format("applied: {}\nwrote {}\n", term_reading(term), out_path);
}

}  // namespace

void add_measured_options(cli::App& c, MeasuredOptions& o) {
  c.add_option("--data", o.data, "the measured figures")->type_name("MEASURED.yaml")->capture_default_str();
  c.add_option("--report", o.report, "write measured.md, measured.json, the tables and plots into DIR")
      ->type_name("DIR");
  c.add_option("--apply", o.apply, "add the chosen Table 3.2 light walk to CALIB (needs its amplitude_reference)")
      ->type_name("CALIB.yaml");
  c.add_option("-o,--output", o.output, "where --apply writes the corrected calibration")->type_name("OUT");
  c.add_flag("--json", o.json, "print the analysis as JSON");
}

int cmd_measured(const MeasuredOptions& o, std::ostream& out, std::ostream& err, const CalibToolEnv& env) {
  if (o.apply.empty() != o.output.empty())
    throw UsageError("measured --apply CALIB.yaml needs -o OUT.yaml, and -o needs --apply");
  const std::string& path = o.data;
  if (path.empty()) throw UsageError("measured needs --data MEASURED.yaml (no default known)");
  // The corrected calibration is checked before any work: never one of the inputs, a link, a device or a leftover.
  if (!o.apply.empty()) files::AtomicFile::check(o.output, {.inputs = {path, o.apply}, .what = "calibration"});
  const MeasuredData d = load_measured_data(path);
  const MaterialAnalysis mat = analyse_materials(d);
  const DistanceAnalysis dist = analyse_distances(d);
  const FitsAnalysis fits = analyse_fits(d);
  const std::vector<CurveAnalysis> curves = analyse_curves(d);
  std::string md = fmt::format(
      "# The calibration loop on the real sensor's measurements\n\nData: `{}` ({} materials, "
      "{} distances, {} published fits, {} factory curves).\n\n",
      std::filesystem::path(path).filename().string(), d.table32.size(), d.table31.size(), d.fits.size(),
      d.sensors.size());
  md += materials_section(d, mat) + distances_section(d, dist) + fits_section(fits) + curves_section(curves);
  if (const auto* report = o.report.empty() ? nullptr : &o.report) {
    namespace fs = std::filesystem;
    std::error_code ec;
    fs::create_directories(*report, ec);
    if (ec || !fs::is_directory(*report))
      throw std::runtime_error(fmt::format("{}: cannot create the report directory", *report));
    // Every report file checked before the first is written: a refused one leaves the report as it was.
    for (const char* name : {"measured_materials.csv", "measured_curves.csv", "measured.json", "measured.md"})
      files::AtomicFile::check((fs::path(*report) / name).string(), {.inputs = {path}, .what = "report file"});
    write_plot_data(*report, d, mat, curves);
    files::write_atomically((fs::path(*report) / "measured.json").string(), report_json(mat, dist, fits, curves));
    std::string note;
    if (run_plot_script(env, *report, note) != 0)
      err << "tinyline calib: warning: " << note << "; report without plots\n";
    for (const char* png : {"measured_materials.png", "measured_curves.png"}) {
      if (fs::exists(fs::path(*report) / png)) md += fmt::format("![{}]({})\n\n", png, png);
    }
    files::write_atomically((fs::path(*report) / "measured.md").string(), md);
    out << fmt::format("wrote {}/measured.md\n", *report);
  }
  if (!o.apply.empty()) apply_walk(mat, o.apply, o.output, out);
  if (o.json) {
    out << report_json(mat, dist, fits, curves);
  } else if (o.report.empty() && o.apply.empty()) {
    out << md;
  }
  return 0;
}

}  // namespace tinyline::tiny_laser_calibration::tool
