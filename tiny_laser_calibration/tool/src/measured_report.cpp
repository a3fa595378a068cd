// SPDX-License-Identifier: Apache-2.0
// `tinyline calib measured`: the calibration loop on every real measurement
// the project holds (measured.hpp), as a report.
#include <algorithm>
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

std::string report_json(const MaterialAnalysis& m, const DistanceAnalysis& dist, const FitsAnalysis& f,
                        const std::vector<CurveAnalysis>& cs) {
  auto hyps = [](const std::vector<EffectHypothesis>& hs) {
    std::string j = "[";
    for (std::size_t i = 0; i < hs.size(); ++i) {
      std::vector<std::string> params, res;
      for (double v : hs[i].params) params.push_back(json_number(v));
      for (double v : hs[i].loo_residual_cm) res.push_back(json_number(v));
      j += fmt::format(
          "{}{{\"effect\": {}, \"form\": {}, \"n_params\": {}, \"params\": [{}], \"loo_rmse_cm\": {}, "
          "\"score_cm\": {}, \"in_sample_rmse_cm\": {}, \"loo_residual_cm\": [{}], \"bound\": {}}}",
          i ? ", " : "", json_string(hs[i].effect), json_string(hs[i].form), hs[i].n_params, fmt::join(params, ", "),
          json_number(hs[i].loo_rmse_cm), json_number(hs[i].score_cm), json_number(hs[i].in_sample_rmse_cm),
          fmt::join(res, ", "), json_string(hs[i].bound));
    }
    return j + "]";
  };
  std::string j = "{\n";
  std::vector<std::string> drivers;
  for (const auto& d : m.drivers) drivers.push_back(json_string(d));
  j += fmt::format("  \"table32\": {{\"before_rmse_cm\": {}, \"best\": {}, \"drivers\": [{}], \"hypotheses\": {}}},\n",
                   json_number(m.before_rmse_cm), m.best, fmt::join(drivers, ", "), hyps(m.hypotheses));
  j += fmt::format(
      "  \"table31\": {{\"before_rmse_cm\": {}, \"best\": {}, \"sd_log_slope\": {}, \"hypotheses\": {}}},\n",
      json_number(dist.before_rmse_cm), dist.best, json_number(dist.sd_log_slope), hyps(dist.hypotheses));
  j += fmt::format("  \"section35\": {{\"noise_exponent\": {}, \"multi_shot_prediction_cm2\": {}}},\n",
                   json_number(f.noise_exponent), json_number(f.multi_shot_prediction_cm2));
  j += "  \"curves\": [";
  for (std::size_t i = 0; i < cs.size(); ++i) {
    const auto& ms = cs[i].models;
    j += fmt::format(
        "{}\n    {{\"sensor\": {}, \"k_min\": {}, \"k_max\": {}, \"best\": {}, \"heldout_rmse_cm\": [{}, {}, {}], "
        "\"in_sample_rmse_cm\": [{}, {}, {}], \"bound\": [{}, {}, {}]}}",
        i ? "," : "", json_string(cs[i].sensor), json_number(cs[i].k_min), json_number(cs[i].k_max), cs[i].best,
        json_number(ms[0].loo_rmse_cm), json_number(ms[1].loo_rmse_cm), json_number(ms[2].loo_rmse_cm),
        json_number(ms[0].in_sample_rmse_cm), json_number(ms[1].in_sample_rmse_cm),
        json_number(ms[2].in_sample_rmse_cm), json_string(ms[0].bound), json_string(ms[1].bound),
        json_string(ms[2].bound));
  }
  return j + "\n  ]\n}\n";
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
                         h ? json_number(h->loo_residual_cm[i]) : "null");
    }
    out.commit();
  }
  files::AtomicStream out((fs::path(dir) / "measured_curves.csv").string());
  // Held out by blocks of distance (each block predicted from a fit on the others), and the
  // chosen model's in-sample residual beside it: the names say which is which.
  out << "sensor,k,l_cm,declared_heldout_residual_cm,best_heldout_residual_cm,best_in_sample_residual_cm\n";
  for (const auto& c : cs) {
    const auto& best = c.models[static_cast<std::size_t>(std::max(c.best, 0))];
    for (std::size_t i = 0; i < c.k.size(); ++i) {
      out << fmt::format("{},{},{},{},{},{}\n", c.sensor, c.k[i], c.l_cm[i], c.models[0].loo_residual_cm[i],
                         best.loo_residual_cm[i], c.best_residual_cm[i]);
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

int cmd_measured(const std::vector<std::string>& argv, std::ostream& out, std::ostream& err, const CalibToolEnv& env) {
  const Options o(argv, {"--data", "--report", "--apply", "-o"}, {"--json"});
  if (o.value("--apply").has_value() != o.value("-o").has_value())
    throw UsageError("measured --apply CALIB.yaml needs -o OUT.yaml, and -o needs --apply");
  if (!o.positional().empty()) throw UsageError("measured takes no positional argument");
  const std::string path = o.value("--data").value_or(env.measured_data);
  if (path.empty()) throw UsageError("measured needs --data MEASURED.yaml (no default known)");
  // The corrected calibration is checked before any work: never one of the inputs, a link, a device or a leftover.
  if (const auto calib = o.value("--apply"))
    files::AtomicFile::check(*o.value("-o"), {.inputs = {path, *calib}, .what = "calibration"});
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
  if (const auto report = o.value("--report")) {
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
  if (const auto in = o.value("--apply")) apply_walk(mat, *in, *o.value("-o"), out);
  if (o.flag("--json")) {
    out << report_json(mat, dist, fits, curves);
  } else if (!o.value("--report") && !o.value("--apply")) {
    out << md;
  }
  return 0;
}

}  // namespace tinyline::tiny_laser_calibration::tool
