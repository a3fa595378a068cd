// SPDX-License-Identifier: Apache-2.0
// `tinyline calib`: fit, diagnose, eval, collect.
#include <spawn.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <optional>
#include <ostream>
#include <sstream>
#include <cstring>

#include <fmt/format.h>
#include <json/json.h>
#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>

#include <tiny_laser_calibration/collect.hpp>
#include <tiny_laser_calibration/discovery.hpp>
#include <tiny_laser_calibration/tool.hpp>

#include "calib_tool_internal.hpp"

extern char** environ;

namespace tinyline::tiny_laser_calibration {

namespace tool {

// ------------------------------------------------------------------ JSON

Json::Value json_number(double v) { return std::isfinite(v) ? Json::Value(v) : Json::Value(Json::nullValue); }

std::string json_text(const Json::Value& v, const char* indentation) {
  Json::StreamWriterBuilder w;
  w["indentation"] = indentation;
  return Json::writeString(w, v) + "\n";
}

// ------------------------------------------------------------------ plots

int run_plot_script(const CalibToolEnv& env, const std::string& dir, std::string& message) {
  if (env.python.empty() || env.plot_script.empty()) {
    message = "no Python interpreter configured for the plots";
    return -1;
  }
  if (!std::filesystem::exists(env.plot_script)) {
    message = fmt::format("plot script {} not found", env.plot_script);
    return -1;
  }
  std::vector<std::string> argv_s = {env.python, env.plot_script, dir};
  std::vector<char*> argv;
  for (auto& s : argv_s) argv.push_back(s.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, env.python.c_str(), nullptr, nullptr, argv.data(), environ);
  if (rc != 0) {
    message = fmt::format("cannot run {}: {}", env.python, std::strerror(rc));
    return -1;
  }
  int status = 0;
  if (waitpid(pid, &status, 0) < 0) {
    message = "lost the plot process";
    return -1;
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    message = fmt::format("{} {} failed (exit status {})", env.python, env.plot_script,
                          WIFEXITED(status) ? WEXITSTATUS(status) : -1);
    return -1;
  }
  return 0;
}

}  // namespace tool

namespace {

using tool::json_number;
using tool::json_text;
using tool::UsageError;

// The residual loop's options (fit --discover, diagnose), as given.
struct LoopOptions {
  std::string select = "driver", group_by = "auto";
  int folds = DiscoveryParams{}.folds, max_terms = DiscoveryParams{}.max_terms;
  unsigned long seed = DiscoveryParams{}.seed;
  std::vector<std::string> exclude;
};

void add_loop_options(cli::App& c, LoopOptions& o) {
  c.add_option("--select", o.select, "read-outs used: the driver's choice per pixel, or every valid one")
      ->check(cli::one_of({"driver", "all"}))
      ->capture_default_str();
  c.add_option("--group-by", o.group_by, "cross-validation groups")
      ->check(cli::one_of({"auto", "distance", "frame"}))
      ->capture_default_str();
  c.add_option("--folds", o.folds, "cross-validation folds")->check(cli::whole(2, 50))->capture_default_str();
  c.add_option("--seed", o.seed, "shuffles groups into hold-out and folds")
      ->check(cli::whole(0, 1 << 30))
      ->capture_default_str();
  c.add_option("--max-terms", o.max_terms, "most terms accepted")->check(cli::whole(0, 20))->capture_default_str();
  c.add_option("--exclude", o.exclude, "covariates never tried")->delimiter(',');
}

ReadoutSelection selection(const std::string& s) {
  return s == "all" ? ReadoutSelection::kAll : ReadoutSelection::kDriver;
}

void apply(const LoopOptions& o, DiscoveryParams& p) {
  p.declared.selection = selection(o.select);
  p.group_by = o.group_by == "distance" ? GroupBy::kTargetDistance
               : o.group_by == "frame"  ? GroupBy::kFrame
                                        : GroupBy::kAuto;
  p.folds = o.folds;
  p.seed = o.seed;
  p.max_terms = o.max_terms;
  p.exclude = o.exclude;
}

// The declared fit's options (fit), as given.
struct FitOptions {
  std::string data, output, report, rsen = "per-pixel", leakage = "fit", weighting = "ones";
  int degree = DeclaredFitParams{}.degree;
  double rsen_value = DeclaredFitParams{}.sensitivity_ratio;
  double temperature_reference = DeclaredFitParams{}.temperature_reference_c;
  bool discover = false, no_temperature = false, json = false;
  LoopOptions loop;
};

// --leakage fit|OFFSET,PER_PULSE.
cli::Validator leakage_values() {
  return {[](std::string& text) -> std::string {
            if (text == "fit") return {};
            const auto comma = text.find(',');
            auto number = [](const std::string& t) { return cli::finite()(t).empty(); };
            if (comma != std::string::npos && number(text.substr(0, comma)) && number(text.substr(comma + 1)))
              return {};
            return "'" + text + "' is not 'fit' or OFFSET,PER_PULSE";
          },
          "fit|OFFSET,PER_PULSE"};
}

void add_fit_options(cli::App& c, FitOptions& o) {
  c.add_option("data", o.data, "the calibration CSV (DATA.csv)")->required()->type_name("DATA.csv");
  c.add_option("-o,--output", o.output, "the calibration written (YAML)")->required()->type_name("CALIB");
  c.add_option("--report", o.report, "write a report (tables, plots, report.md) into DIR")->type_name("DIR");
  c.add_flag("--discover", o.discover, "run the residual loop and add every effect it accepts to the model");
  c.add_option("--degree", o.degree, "polynomial degree of Eq. 3.18")->check(cli::whole(1, 12))->capture_default_str();
  c.add_option("--rsen", o.rsen, "per-pixel sensitivity ratio around --rsen-value, or one value")
      ->check(cli::one_of({"per-pixel", "fixed"}))
      ->capture_default_str();
  c.add_option("--rsen-value", o.rsen_value, "the common Rsen, measured under ambient light")
      ->check(cli::positive())
      ->capture_default_str();
  c.add_option("--leakage", o.leakage, "fit Vle, or measured values [charge_unit, charge_unit/pulse]")
      ->check(leakage_values())
      ->capture_default_str();
  c.add_option("--weighting", o.weighting, "K_i of Eq. 3.20")
      ->check(cli::one_of({"ones", "inverse-variance"}))
      ->capture_default_str();
  c.add_flag("--no-temperature", o.no_temperature, "no temperature offset term");
  c.add_option("--temperature-reference", o.temperature_reference, "T_ref of the offset [degC]")
      ->check(cli::finite())
      ->capture_default_str();
  c.add_flag("--json", o.json, "print the loop's summary as JSON");
  add_loop_options(c, o.loop);
}

DiscoveryParams discovery_params(const FitOptions& o) {
  DiscoveryParams p;
  auto& d = p.declared;
  d.degree = o.degree;
  d.sensitivity_ratio_mode = o.rsen == "fixed" ? SensitivityRatioMode::kFixed : SensitivityRatioMode::kPerPixel;
  d.sensitivity_ratio = o.rsen_value;
  if (o.leakage != "fit") {
    const auto comma = o.leakage.find(',');
    d.fit_leakage = false;
    d.leakage_offset = std::stod(o.leakage.substr(0, comma));
    d.leakage_per_pulse = std::stod(o.leakage.substr(comma + 1));
  }
  d.weighting = o.weighting == "inverse-variance" ? DistanceWeighting::kInverseVariance : DistanceWeighting::kOnes;
  d.fit_temperature = !o.no_temperature;
  d.temperature_reference_c = o.temperature_reference;
  apply(o.loop, p);
  return p;
}

struct DiagnoseOptions {
  std::string data, calib, report;
  bool json = false;
  LoopOptions loop;
};

void add_diagnose_options(cli::App& c, DiagnoseOptions& o) {
  c.add_option("data", o.data, "the calibration CSV (DATA.csv)")->required()->type_name("DATA.csv");
  c.add_option("--calib", o.calib, "the calibration diagnosed")->required()->type_name("CALIB.yaml");
  c.add_option("--report", o.report, "the report's folder")->required()->type_name("DIR");
  c.add_flag("--json", o.json, "print the summary as JSON");
  add_loop_options(c, o.loop);
}

struct EvalOptions {
  std::string data, calib, select = "driver";
};

void add_eval_options(cli::App& c, EvalOptions& o) {
  c.add_option("data", o.data, "the calibration CSV (DATA.csv)")->required()->type_name("DATA.csv");
  c.add_option("--calib", o.calib, "the calibration evaluated")->required()->type_name("CALIB.yaml");
  c.add_option("--select", o.select, "read-outs used: the driver's choice per pixel, or every valid one")
      ->check(cli::one_of({"driver", "all"}))
      ->capture_default_str();
}

struct CollectOptions {
  std::string bag, output, pixels;
  CollectParams params;
};

// --pixels FROM-TO, 0 <= FROM <= TO <= 271.
cli::Validator pixel_range() {
  return {
      [](std::string& text) -> std::string {
        int from = 0, to = 0;
        char dash = 0;
        std::istringstream in(text);
        if (in >> from >> dash >> to && dash == '-' && (in >> std::ws).eof() && 0 <= from && from <= to && to <= 271)
          return {};
        return "'" + text + "' is not FROM-TO with 0 <= FROM <= TO <= 271";
      },
      "FROM-TO"};
}

void add_collect_options(cli::App& c, CollectOptions& o) {
  auto& p = o.params;
  c.add_option("bag", o.bag, "a recorded bag (raw scans and the simulator's scan_truth)")->required()->type_name("BAG");
  c.add_option("-o,--output", o.output, "the calibration CSV written")->required()->type_name("DATA");
  c.add_option("--raw-topic", p.raw_topic, "RawScan topic (default: the bag's only one)");
  c.add_option("--truth-topic", p.truth_topic, "ScanTruth topic (default: the bag's only one)");
  c.add_option("--sensor", p.sensor, "the sensor whose sets to take (default: the raw scans' one frame)");
  c.add_option("--max-gap", p.max_pair_gap_s, "largest stamp gap of a scan and its truth [s]")
      ->check(cli::non_negative())
      ->capture_default_str();
  c.add_option("--pixel-step", p.pixel_step, "every N-th effective pixel")
      ->check(cli::whole(1, 256))
      ->capture_default_str();
  c.add_flag("--keep-mixed", p.keep_mixed, "keep pixels whose footprint spans several surfaces");
  c.add_flag("--incidence", p.incidence_column, "add an incidence_deg column (the ray's angle to the surface normal)");
  c.add_option("--positions", p.positions_csv,
               "a real sensor on a rail: no truth topic; the tape-measure log t_from_s,t_to_s,distance_m[,material] "
               "(s since the first raw scan)")
      ->type_name("LOG.csv");
  c.add_option("--focal-mm", p.focal_mm, "its lens: each pixel's range is distance / cos(ray angle)")
      ->check(cli::positive())
      ->capture_default_str();
  c.add_option("--pixels", o.pixels, "keep these pixels only (e.g. the central ones)")->check(pixel_range());
}

std::string cm(double m) { return std::isfinite(m) ? fmt::format("{:.3f} cm", m * 100.0) : "n/a"; }

// ------------------------------------------------------------------ report

std::vector<std::string> unique(std::vector<std::string> v) {
  std::vector<std::string> out;
  for (auto& s : v) {
    if (std::find(out.begin(), out.end(), s) == out.end()) out.push_back(std::move(s));
  }
  return out;
}

struct ReportContext {
  std::string command;  // fit or diagnose
  std::string data_path;
  std::string model_path;
  const CalibrationDataset* data = nullptr;
  const DiscoveryParams* params = nullptr;
  const DiscoveryResult* result = nullptr;
  const CalibrationModel* covariate_model = nullptr;  // gives the covariate values of the residual rows
  const CalibrationModel* final_model = nullptr;      // the curve
  std::size_t used = 0;
  std::vector<std::string> fit_notes;
};

Json::Value score_json(const std::string& covariate, TermForm form) {
  Json::Value j;
  j["covariate"] = covariate;
  j["form"] = std::string(to_string(form));
  return j;
}

Json::Value effect_json(const DiscoveredEffect& e) {
  Json::Value j = score_json(e.covariate, e.form);
  j["rmse_before_m"] = json_number(e.rmse_before_m);
  j["rmse_after_m"] = json_number(e.rmse_after_m);
  j["cv_rmse_before_m"] = json_number(e.cv_rmse_before_m);
  j["cv_rmse_after_m"] = json_number(e.cv_rmse_after_m);
  j["gain"] = json_number(e.gain);
  j["z"] = json_number(e.z);
  j["written"] = e.written;
  j["reading"] = e.reading;
  return j;
}

Json::Value rounds_json(const DiscoveryResult& r) {
  Json::Value rounds(Json::arrayValue);
  for (const auto& round : r.rounds) {
    Json::Value scores(Json::arrayValue);
    for (const auto& s : round) {
      Json::Value j = score_json(s.covariate, s.form);
      j["cv_rmse_m"] = json_number(s.cv_rmse_m);
      j["gain"] = json_number(s.gain);
      j["z"] = json_number(s.z);
      j["passes"] = s.passes;
      scores.append(j);
    }
    rounds.append(scores);
  }
  return rounds;
}

Json::Value strings_json(const std::vector<std::string>& v) {
  Json::Value a(Json::arrayValue);
  for (const auto& s : v) a.append(s);
  return a;
}

std::string summary_json(const ReportContext& c) {
  const auto& r = *c.result;
  const auto& p = *c.params;
  Json::Value j;
  j["command"] = c.command;
  j["data"] = c.data_path;
  j["model"] = c.model_path;
  j["rows"] = Json::UInt64(c.data->size());
  j["used"] = Json::UInt64(c.used);
  j["selection"] = p.declared.selection == ReadoutSelection::kDriver ? "driver" : "all";
  j["grouping"] = std::string(to_string(r.grouping));
  j["groups"] = Json::UInt64(r.groups);
  j["holdout_groups"] = Json::UInt64(r.holdout_groups);
  j["heldout_readouts"] = Json::UInt64(r.heldout_eval_rows.size());
  j["rmse_before_m"] = json_number(r.rmse_before_m);
  j["rmse_after_m"] = json_number(r.rmse_after_m);
  j["effects"] = Json::Value(Json::arrayValue);
  for (const auto& e : r.effects) j["effects"].append(effect_json(e));
  auto& acceptance = j["acceptance"];
  acceptance["folds"] = p.folds;
  acceptance["alpha"] = json_number(p.alpha);
  acceptance["z_threshold"] = json_number(r.z_threshold);
  acceptance["min_relative_gain"] = json_number(p.min_relative_gain);
  acceptance["max_terms"] = p.max_terms;
  j["candidates"] = strings_json(r.candidates);
  j["rounds"] = rounds_json(r);
  j["rejected_on_holdout"] = Json::Value(Json::arrayValue);
  for (const auto& k : r.rejected_on_holdout) j["rejected_on_holdout"].append(score_json(k.covariate, k.form));
  std::vector<std::string> notes = r.notes;
  notes.insert(notes.end(), c.fit_notes.begin(), c.fit_notes.end());
  j["notes"] = strings_json(unique(std::move(notes)));
  return json_text(j);
}

// Held-out read-outs with every candidate covariate and both residuals.
std::string residuals_csv(const ReportContext& c) {
  const auto& data = *c.data;
  const auto& r = *c.result;
  std::ostringstream out;
  out << "line,distance_m,target_group,material";
  for (Covariate k : builtin_covariates()) out << ',' << covariate_name(k);
  for (const auto& n : data.extra_names) out << ',' << n;
  out << ",residual_before_m,residual_after_m\n";
  const auto groups = target_distance_groups(data);
  const auto& model = *c.covariate_model;
  std::vector<std::size_t> rows = r.heldout_eval_rows;
  const auto sub = readouts_for_model(data.subset(rows), model);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const std::size_t i = rows[k];
    const Readout& ro = data.readouts[i];
    const auto ev = model.evaluate(sub[k]);
    std::string line = fmt::format("{},{},{},", data.line[i], data.distance_m[i], groups[i]);
    if (data.has_material && data.material[i] >= 0) line += data.materials[static_cast<std::size_t>(data.material[i])];
    for (Covariate kind : builtin_covariates()) {
      const double v = CalibrationModel::Impl::covariate_value(kind, -1, ro, ev.ratio, ev.declared_distance_m,
                                                               model.impl().amplitude_reference);
      line += std::isfinite(v) ? fmt::format(",{}", v) : ",";
    }
    for (double v : ro.extra) line += fmt::format(",{}", v);
    const double b = r.heldout_residual_before_m[k], a = r.heldout_residual_after_m[k];
    line += (std::isfinite(b) ? fmt::format(",{}", b) : ",") + (std::isfinite(a) ? fmt::format(",{}", a) : ",");
    out << line << '\n';
  }
  return out.str();
}

// Data points (X, truth) under the final model and the model's polynomial.
std::string curve_csv(const ReportContext& c) {
  const auto& data = *c.data;
  const auto& m = c.final_model->impl();
  std::ostringstream out;
  out << "kind,ratio,distance_m\n";
  const auto rows = select_readouts(data, {}, m.validity, c.params->declared.selection);
  const std::size_t step = std::max<std::size_t>(1, rows.size() / 6000);
  for (std::size_t k = 0; k < rows.size(); k += step) {
    const double x = m.ratio(data.readouts[rows[k]]);
    if (std::isfinite(x)) out << fmt::format("data,{},{}\n", x, data.distance_m[rows[k]]);
  }
  const double margin = m.ratio_margin * (m.ratio_max - m.ratio_min);
  for (int i = 0; i <= 200; ++i) {
    const double x = m.ratio_min - margin + (m.ratio_max - m.ratio_min + 2 * margin) * i / 200.0;
    out << fmt::format("model,{},{}\n", x, m.polynomial_m(x));
  }
  return out.str();
}

std::string report_markdown(const ReportContext& c, const std::string& dir, const std::string& plot_note) {
  namespace fs = std::filesystem;
  const auto& r = *c.result;
  const auto& p = *c.params;
  std::string md;
  md += fmt::format("# Calibration report: `tinyline calib {}`\n\n", c.command);
  md += fmt::format("- data: `{}` ({} rows; {} read-outs used, {})\n", c.data_path, c.data->size(), c.used,
                    p.declared.selection == ReadoutSelection::kDriver ? "the driver's choice per pixel and frame"
                                                                      : "every valid read-out");
  md += fmt::format("- model: `{}`\n", c.model_path);
  md += fmt::format("- held out: {} of {} {} groups ({} read-outs), never used to fit or select\n\n", r.holdout_groups,
                    r.groups, to_string(r.grouping), r.heldout_eval_rows.size());
  md += "```\n" + c.final_model->describe() + "```\n\n";
  md += "## Error on held-out data\n\n| | RMSE |\n|---|---|\n";
  md +=
      fmt::format("| {} | {} |\n", c.command == "fit" ? "declared model" : "calibration as given", cm(r.rmse_before_m));
  md += fmt::format("| with the accepted terms | {} |\n\n", cm(r.rmse_after_m));
  md += "## Effects found\n\n";
  if (r.effects.empty()) {
    md += fmt::format(
        "None: no candidate removed {:.0f}% of the cross-validated squared error with z above the "
        "round's Bonferroni threshold ({:.2f}).\n\n",
        100.0 * p.min_relative_gain, r.z_threshold);
  } else {
    md +=
        "| covariate | form | held-out RMSE before | after | CV gain | z | in physical units |\n"
        "|---|---|---|---|---|---|---|\n";
    for (const auto& e : r.effects) {
      md += fmt::format("| {} | {} | {} | {} | {:.1f}% | {:.1f} | {}{} |\n", e.covariate, to_string(e.form),
                        cm(e.rmse_before_m), cm(e.rmse_after_m), 100.0 * e.gain, e.z, e.reading,
                        e.written ? "" : " (reported, not written)");
    }
    md += "\n";
  }
  if (!r.rounds.empty()) {
    md += fmt::format(
        "## Candidates of the first round\n\nAccepted when the gain exceeds {:.0f}% and z exceeds {:.2f} "
        "(one-sided, alpha {} shared over every test of every round: two paired statistics per "
        "candidate).\n\n",
        100.0 * p.min_relative_gain, r.z_threshold, p.alpha);
    md += "| covariate | form | CV RMSE | gain | z | passes |\n|---|---|---|---|---|---|\n";
    for (const auto& s : r.rounds.front()) {
      md += fmt::format("| {} | {} | {} | {:.1f}% | {:.1f} | {} |\n", s.covariate, to_string(s.form), cm(s.cv_rmse_m),
                        100.0 * s.gain, s.z, s.passes ? "yes" : "no");
    }
    md += "\n";
  }
  md += "## Figures\n\n";
  if (!plot_note.empty()) md += fmt::format("Plots were not drawn: {}.\n\n", plot_note);
  auto figure = [&](const std::string& file, const std::string& caption) {
    if (fs::exists(fs::path(dir) / file)) md += fmt::format("![{}]({})\n\n*{}*\n\n", caption, file, caption);
  };
  figure("curve.png", "Fitted curve: distance against the charge ratio X (Eq. 3.18)");
  figure("error_by_distance.png", "Held-out error by target distance, before and after");
  std::vector<std::string> names;
  for (Covariate k : builtin_covariates()) names.emplace_back(covariate_name(k));
  names.insert(names.end(), c.data->extra_names.begin(), c.data->extra_names.end());
  for (const auto& n : names) figure("residual_" + n + ".png", "Held-out residual against " + n + ", before and after");
  figure("residual_material.png", "Held-out error by material (a diagnosis: the driver does not know the material)");
  std::vector<std::string> notes = r.notes;
  notes.insert(notes.end(), c.fit_notes.begin(), c.fit_notes.end());
  notes = unique(std::move(notes));
  if (!notes.empty()) {
    md += "## Notes\n\n";
    for (const auto& n : notes) md += "- " + n + "\n";
  }
  return md;
}

// The report's files, each checked and its temporary made before any work, so
// that a report that cannot be written fails before any output is replaced.
struct ReportFiles {
  std::string dir;
  files::AtomicFile summary, residuals, curve, markdown;
};

ReportFiles open_report(const std::string& dir, const std::vector<std::string>& inputs) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    throw std::runtime_error(fmt::format("{}: cannot create the report directory", dir));
  auto open = [&](const char* name) {
    return files::AtomicFile((fs::path(dir) / name).string(), {.inputs = inputs, .what = "report file"});
  };
  return {dir, open("summary.json"), open("residuals.csv"), open("curve.csv"), open("report.md")};
}

void write_report(const ReportContext& c, ReportFiles& f, const CalibToolEnv& env, std::ostream& err) {
  f.summary.write(summary_json(c));
  f.residuals.write(residuals_csv(c));
  f.curve.write(curve_csv(c));
  f.summary.commit();
  f.residuals.commit();
  f.curve.commit();  // the plot script reads the tables
  std::string note;
  if (tool::run_plot_script(env, f.dir, note) != 0)
    err << "tinyline calib: warning: " << note << "; report without plots\n";
  f.markdown.write(report_markdown(c, f.dir, note));
  f.markdown.commit();
}

void print_summary(std::ostream& out, const DiscoveryResult& r) {
  out << fmt::format("held-out RMSE: {} before, {} after ({} of {} {} groups held out)\n", cm(r.rmse_before_m),
                     cm(r.rmse_after_m), r.holdout_groups, r.groups, to_string(r.grouping));
  if (r.effects.empty()) {
    out << "effects: none\n";
  } else {
    for (const auto& e : r.effects) {
      out << fmt::format("effect: {} ({}): {} -> {} held out, CV gain {:.1f}%, z {:.1f}{}\n", e.covariate,
                         to_string(e.form), cm(e.rmse_before_m), cm(e.rmse_after_m), 100.0 * e.gain, e.z,
                         e.written ? "" : " (reported, not written: see the notes)");
      if (!e.reading.empty()) out << fmt::format("  {}\n", e.reading);
    }
  }
}

// ------------------------------------------------------------------ commands

// Why `model` must not be written ("" when it may): the driver's own loader
// refuses it, or its error is no number (1e308 m of truth gave "rmse_m": null).
std::string unwritable(const CalibrationModel& model, double rmse_m, const std::string& path) {
  if (!std::isfinite(rmse_m)) return "the fit's RMSE is not a finite number: the data cannot be fitted";
  try {
    (void)CalibrationModel::from_yaml(model.to_yaml(), path);
  } catch (const std::exception& e) {
    return fmt::format("the fitted model is not one the driver can load: {}", e.what());
  }
  return {};
}

int cmd_fit(const FitOptions& o, std::ostream& out, std::ostream& err, const CalibToolEnv& env) {
  const DiscoveryParams p = discovery_params(o);
  const bool report = !o.report.empty();
  const std::string& data_path = o.data;
  // Every output checked before the work (never the input, a link or a device)
  // and replaced only when all of them are made: the model last.
  files::AtomicFile output_file(o.output, {.inputs = {data_path}, .what = "calibration"});
  std::optional<ReportFiles> report_files;
  if (report) report_files = open_report(o.report, {data_path, o.output});
  const auto data = read_calibration_csv(data_path);

  // The declared fit on every row: what is written without --discover, and the in-sample figures.
  const auto declared = fit_declared_model(data, p.declared);
  if (!declared.status.ok()) {
    err << fmt::format("tinyline calib fit: error: {}: {}\n", data_path, declared.status.message);
    return 1;
  }
  out << fmt::format(
      "declared model: {} of {} rows used ({} saturated, {} too dark, {} not the driver's choice), "
      "in-sample RMSE {}\n",
      declared.used, declared.rows, declared.saturated, declared.too_dark, declared.not_selected, cm(declared.rmse_m));
  out << declared.model.describe();
  for (const auto& n : declared.notes) out << "note: " << n << "\n";

  CalibrationModel model = declared.model;
  std::optional<DiscoveryResult> loop;
  if (o.discover || report) {
    DiscoveryParams lp = p;
    if (!o.discover) lp.max_terms = 0;  // the held-out split for the report, no terms
    loop = discover_effects(data, lp);
    if (!loop->status.ok()) {
      err << fmt::format("tinyline calib fit: error: {}: {}\n", data_path, loop->status.message);
      return 1;
    }
    print_summary(out, *loop);
    model = loop->model;
  }
  // The per-pixel range SD the driver publishes (section 3.5); in the YAML, not printed.
  model.impl().noise = fit_noise_law(model, data);
  if (const std::string why = unwritable(model, declared.rmse_m, o.output); !why.empty()) {
    err << fmt::format("tinyline calib fit: error: {}: {}\n", data_path, why);
    return 1;
  }
  output_file.write(model.to_yaml());
  const ReportContext c{.command = "fit",
                        .data_path = data_path,
                        .model_path = o.output,
                        .data = &data,
                        .params = &p,
                        .result = loop ? &*loop : nullptr,
                        .covariate_model = loop ? &loop->train_before : nullptr,
                        .final_model = &model,
                        .used = declared.used,
                        .fit_notes = declared.notes};
  if (report) write_report(c, *report_files, env, err);
  output_file.commit();
  out << fmt::format("wrote {}\n", o.output);
  if (report) out << fmt::format("wrote {}/report.md\n", o.report);
  if (o.json && loop) out << summary_json(c);
  return 0;
}

int cmd_diagnose(const DiagnoseOptions& o, std::ostream& out, std::ostream& err, const CalibToolEnv& env) {
  DiscoveryParams p;
  apply(o.loop, p);
  auto report_files = open_report(o.report, {o.data, o.calib});
  const auto model = CalibrationModel::load(o.calib);
  p.declared.validity = model.validity();
  const std::string& data_path = o.data;
  const auto data = read_calibration_csv(data_path);
  const auto r = diagnose_model(model, data, p);
  if (!r.status.ok()) {
    err << fmt::format("tinyline calib diagnose: error: {}: {}\n", data_path, r.status.message);
    return 1;
  }
  print_summary(out, r);
  ReportContext c;
  c.command = "diagnose";
  c.data_path = data_path;
  c.model_path = o.calib;
  c.data = &data;
  c.params = &p;
  c.result = &r;
  c.covariate_model = &model;
  c.final_model = &model;
  c.used = r.train_rows.size() + r.heldout_eval_rows.size();
  write_report(c, report_files, env, err);
  out << fmt::format("wrote {}/report.md\n", o.report);
  if (o.json) out << summary_json(c);
  return 0;
}

int cmd_eval(const EvalOptions& o, std::ostream& out, std::ostream& err) {
  const auto model = CalibrationModel::load(o.calib);
  // A term on a lagged temperature needs that column: derived from the data's own temperatures.
  const auto data = with_derived_covariates(read_calibration_csv(o.data), model.extra_covariates());
  const auto s = evaluate_model(model, data, {}, selection(o.select));
  if (s.n == 0) {
    err << fmt::format(
        "tinyline calib eval: error: {}: the calibration gives no distance for any read-out ({} "
        "saturated, {} too dark, {} outside its ratio range, {} missing a covariate)\n",
        o.data, s.saturated, s.too_dark, s.out_of_range, s.missing_covariate);
    return 1;
  }
  Json::Value j;
  j["n"] = Json::UInt64(s.n);
  j["rmse_m"] = json_number(s.rmse_m);
  j["bias_m"] = json_number(s.bias_m);
  j["p95_abs_m"] = json_number(s.p95_abs_m);
  out << json_text(j, "");
  if (s.out_of_range || s.missing_covariate) {
    err << fmt::format("note: left out {} read-outs outside the calibrated ratio range and {} missing a covariate\n",
                       s.out_of_range, s.missing_covariate);
  }
  return 0;
}

int cmd_collect(const CollectOptions& o, std::ostream& out, std::ostream& err) {
  CollectParams p = o.params;
  if (!o.pixels.empty()) {
    const auto dash = o.pixels.find('-');
    p.pixel_from = std::stoi(o.pixels.substr(0, dash));
    p.pixel_to = std::stoi(o.pixels.substr(dash + 1));
  }
  files::AtomicFile output_file(o.output, {.inputs = {o.bag, p.positions_csv}, .what = "data file"});
  const auto r = collect_calibration_data(o.bag, p);
  for (const auto& n : r.notes) err << "note: " << n << "\n";
  if (!r.status.ok()) {
    // The code too: a bag's "open failed" or "crc mismatch" tells what to do about it.
    err << fmt::format("tinyline calib collect: error: {}\n", r.status.str());
    return 1;
  }
  std::ostringstream csv;
  write_calibration_csv(r.data, csv);
  output_file.write(csv.str());
  output_file.commit();
  std::size_t materials = r.data.materials.size();
  if (p.positions_csv.empty()) {
    out << fmt::format("{}: {} raw scans on {}, {} truths on {}, {} paired\n", o.bag, r.raw_scans, r.raw_topic,
                       r.truths, r.truth_topic, r.paired);
  } else {
    out << fmt::format("{}: {} raw scans on {}, {} at a logged rail position, {} between positions\n", o.bag,
                       r.raw_scans, r.raw_topic, r.paired, r.between_positions);
  }
  out << fmt::format("pixels left out per set: {} dark, {} without a range, {} unlit, {} mixed (totals over sets)\n",
                     r.dark_pixels, r.no_range, r.unlit, r.mixed);
  out << fmt::format("wrote {} rows ({} material{}) to {}\n", r.data.size(), materials, materials == 1 ? "" : "s",
                     o.output);
  return 0;
}

// Every sub-command's options, filled by one parse.
struct CalibCommandLine {
  cli::App app{
      "The calibration tool: fit the declared model, discover the effects it lacks, diagnose, evaluate, "
      "collect data from bags, and run the loop on the real sensor's measurements.",
      "tinyline calib"};
  FitOptions fit;
  DiagnoseOptions diagnose;
  EvalOptions eval;
  CollectOptions collect;
  tool::MeasuredOptions measured;

  explicit CalibCommandLine(const CalibToolEnv& env) {
    add_fit_options(*app.add_subcommand("fit",
                                        "fit the declared model (Eq. 3.16, 3.18, 3.20, 3.3.4); with --discover run "
                                        "the residual loop and add every effect it accepts to the model written"),
                    fit);
    add_diagnose_options(*app.add_subcommand("diagnose", "the residual analysis of a calibration on data, alone"),
                         diagnose);
    add_eval_options(
        *app.add_subcommand("eval", "prints {\"n\", \"rmse_m\", \"bias_m\", \"p95_abs_m\"} over the valid read-outs"),
        eval);
    add_collect_options(
        *app.add_subcommand("collect",
                            "a recorded bag (raw scans + the simulator's scan_truth) -> the calibration CSV"),
        collect);
    measured.data = env.measured_data;
    tool::add_measured_options(*app.add_subcommand("measured",
                                                   "the loop on the real sensor's measured figures (Tables 3.1, 3.2, "
                                                   "section 3.5, the five real sensors' factory curves)"),
                               measured);
    app.require_subcommand(1);
  }

  int run(const std::string& sub, std::ostream& out, std::ostream& err, const CalibToolEnv& env) const {
    if (sub == "fit") return cmd_fit(fit, out, err, env);
    if (sub == "diagnose") return cmd_diagnose(diagnose, out, err, env);
    if (sub == "eval") return cmd_eval(eval, out, err);
    if (sub == "collect") return cmd_collect(collect, out, err);
    return tool::cmd_measured(measured, out, err, env);
  }
};

}  // namespace

int run_calib_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err,
                      const CalibToolEnv& env) {
  CalibCommandLine line(env);
  if (const auto rc = cli::parse_command_line(line.app, args, out, err)) return *rc;
  const std::string sub = line.app.parsed_subcommands().front()->name();
  try {
    return line.run(sub, out, err, env);
  } catch (const UsageError& e) {
    err << fmt::format("tinyline calib {}: {}\nRun with --help for more information.\n", sub, e.what());
    return 2;
  } catch (const std::exception& e) {
    err << fmt::format("tinyline calib {}: error: {}\n", sub, e.what());
    return 1;
  }
}

}  // namespace tinyline::tiny_laser_calibration
