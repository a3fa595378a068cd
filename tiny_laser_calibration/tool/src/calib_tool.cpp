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
#include <tinyline/common/files.hpp>

#include <tiny_laser_calibration/collect.hpp>
#include <tiny_laser_calibration/discovery.hpp>
#include <tiny_laser_calibration/tool.hpp>

#include "calib_tool_internal.hpp"

extern char** environ;

namespace tinyline::tiny_laser_calibration {

namespace tool {

// ------------------------------------------------------------------ arguments

Options::Options(const std::vector<std::string>& argv, const std::vector<std::string>& valued,
                 const std::vector<std::string>& flags) {
  for (std::size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    if (a.size() > 1 && a[0] == '-' &&
        !(a.size() > 1 && (std::isdigit(static_cast<unsigned char>(a[1])) || a[1] == '.'))) {
      if (std::find(flags.begin(), flags.end(), a) != flags.end()) {
        flags_.push_back(a);
      } else if (std::find(valued.begin(), valued.end(), a) != valued.end()) {
        if (i + 1 >= argv.size()) throw UsageError(fmt::format("option {} needs a value", a));
        values_[a] = argv[++i];
      } else {
        throw UsageError(fmt::format("unknown option '{}'", a));
      }
    } else {
      positional_.push_back(a);
    }
  }
}

bool Options::flag(const std::string& f) const { return std::find(flags_.begin(), flags_.end(), f) != flags_.end(); }

std::optional<std::string> Options::value(const std::string& name) const {
  const auto it = values_.find(name);
  if (it == values_.end()) return std::nullopt;
  return it->second;
}

double Options::number(const std::string& name, double fallback) const {
  const auto v = value(name);
  if (!v) return fallback;
  try {
    std::size_t used = 0;
    const double x = std::stod(*v, &used);
    if (used != v->size() || !std::isfinite(x)) throw std::invalid_argument("");
    return x;
  } catch (const std::exception&) {
    throw UsageError(fmt::format("option {}: '{}' is not a number", name, *v));
  }
}

int Options::integer(const std::string& name, int fallback, int lo, int hi) const {
  const double x = number(name, fallback);
  if (x != std::floor(x) || x < lo || x > hi) {
    throw UsageError(fmt::format("option {}: '{}' is not an integer in [{}, {}]", name, *value(name), lo, hi));
  }
  return static_cast<int>(x);
}

// ------------------------------------------------------------------ JSON

std::string json_string(const std::string& s) {
  std::string o = "\"";
  for (const char c : s) {
    switch (c) {
      case '"': o += "\\\""; break;
      case '\\': o += "\\\\"; break;
      case '\n': o += "\\n"; break;
      case '\r': o += "\\r"; break;
      case '\t': o += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          o += fmt::format("\\u{:04x}", static_cast<int>(c));
        } else {
          o += c;
        }
    }
  }
  return o + "\"";
}

std::string json_number(double v) { return std::isfinite(v) ? fmt::format("{}", v) : "null"; }

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
using tool::json_string;
using tool::Options;
using tool::UsageError;

constexpr const char* kUsage =
    "usage: tinyline calib <command> ...\n"
    "\n"
    "  fit DATA.csv -o CALIB.yaml [--discover] [--report DIR] [options]\n"
    "      fit the declared model (Eq. 3.16, 3.18, 3.20, 3.3.4); with --discover run the\n"
    "      residual loop and add every effect it accepts to the model written\n"
    "  diagnose DATA.csv --calib CALIB.yaml --report DIR [options]\n"
    "      the residual analysis of a calibration on data, alone\n"
    "  eval DATA.csv --calib CALIB.yaml [--select driver|all]\n"
    "      prints {\"n\", \"rmse_m\", \"bias_m\", \"p95_abs_m\"} over the valid read-outs\n"
    "  measured [--data MEASURED.yaml] [--report DIR] [--json] [--apply CALIB.yaml -o OUT.yaml]\n"
    "      the loop on the real sensor's measured figures (Tables 3.1, 3.2, section 3.5, the\n"
    "      five real sensors' factory curves); default data: the package's measured.yaml\n"
    "      --apply adds the chosen Table 3.2 light walk to CALIB (needs its amplitude_reference)\n"
    "  collect BAG -o DATA.csv [options]\n"
    "      a recorded bag (raw scans + the simulator's scan_truth) -> the calibration CSV\n"
    "\n"
    "fit options:\n"
    "  --degree N                 polynomial degree of Eq. 3.18 (default 6)\n"
    "  --rsen per-pixel|fixed     per-pixel sensitivity ratio around --rsen-value, or one value (default per-pixel)\n"
    "  --rsen-value V             the common Rsen, measured under ambient light (default 1)\n"
    "  --leakage fit|OFFSET,PER_PULSE   fit Vle or use measured values [charge_unit, charge_unit/pulse]\n"
    "  --weighting ones|inverse-variance   K_i of Eq. 3.20 (default ones)\n"
    "  --no-temperature           no temperature offset term\n"
    "  --temperature-reference C  T_ref of the offset (default 48, the warm temperature)\n"
    "residual loop options (fit --discover, diagnose):\n"
    "  --select driver|all        read-outs used: the driver's choice per pixel (default) or every valid one\n"
    "  --group-by auto|distance|frame   cross-validation groups (default auto)\n"
    "  --folds K                  (default 5)   --seed N   (default 1)   --max-terms N (default 4)\n"
    "  --exclude a,b,...          covariates never tried\n"
    "  --json                     print the summary as JSON\n"
    "collect options:\n"
    "  --raw-topic T / --truth-topic T   RawScan / ScanTruth topics (default: the bag's only one)\n"
    "  --sensor NAME              the sensor whose sets to take (default: the raw scans' one frame)\n"
    "  --max-gap S                largest stamp gap of a scan and its truth (default 0.01 s)\n"
    "  --pixel-step N             every N-th effective pixel (default 1)\n"
    "  --keep-mixed               keep pixels whose footprint spans several surfaces\n"
    "  --incidence                add an incidence_deg column (angle of the ray to the surface normal)\n"
    "  --positions LOG.csv        a real sensor on a rail: no truth topic; the tape-measure log\n"
    "                             t_from_s,t_to_s,distance_m[,material] (s since the first raw scan)\n"
    "  --focal-mm F               its lens (default 3.6): each pixel's range is distance / cos(ray angle)\n"
    "  --pixels FROM-TO           keep these pixels only (e.g. the central ones)\n";

std::vector<std::string> split_list(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

const std::vector<std::string> kLoopValued = {"--select", "--group-by",  "--folds",
                                              "--seed",   "--max-terms", "--exclude"};
const std::vector<std::string> kFitValued = {"-o",        "--output",    "--report",
                                             "--degree",  "--rsen",      "--rsen-value",
                                             "--leakage", "--weighting", "--temperature-reference"};

void apply_loop_options(const Options& o, DiscoveryParams& p) {
  if (const auto s = o.value("--select")) {
    if (*s == "driver") {
      p.declared.selection = ReadoutSelection::kDriver;
    } else if (*s == "all") {
      p.declared.selection = ReadoutSelection::kAll;
    } else {
      throw UsageError(fmt::format("--select: '{}' is not driver or all", *s));
    }
  }
  if (const auto g = o.value("--group-by")) {
    if (*g == "auto") {
      p.group_by = GroupBy::kAuto;
    } else if (*g == "distance") {
      p.group_by = GroupBy::kTargetDistance;
    } else if (*g == "frame") {
      p.group_by = GroupBy::kFrame;
    } else {
      throw UsageError(fmt::format("--group-by: '{}' is not auto, distance or frame", *g));
    }
  }
  p.folds = o.integer("--folds", p.folds, 2, 50);
  p.seed = static_cast<std::uint64_t>(o.integer("--seed", static_cast<int>(p.seed), 0, 1 << 30));
  p.max_terms = o.integer("--max-terms", p.max_terms, 0, 20);
  if (const auto e = o.value("--exclude")) p.exclude = split_list(*e);
}

void apply_fit_options(const Options& o, DeclaredFitParams& p) {
  p.degree = o.integer("--degree", p.degree, 1, 12);
  if (const auto r = o.value("--rsen")) {
    if (*r == "per-pixel") {
      p.sensitivity_ratio_mode = SensitivityRatioMode::kPerPixel;
    } else if (*r == "fixed") {
      p.sensitivity_ratio_mode = SensitivityRatioMode::kFixed;
    } else {
      throw UsageError(fmt::format("--rsen: '{}' is not per-pixel or fixed", *r));
    }
  }
  p.sensitivity_ratio = o.number("--rsen-value", p.sensitivity_ratio);
  if (!(p.sensitivity_ratio > 0.0)) throw UsageError("--rsen-value must be positive");
  if (const auto l = o.value("--leakage")) {
    if (*l != "fit") {
      const auto parts = split_list(*l);
      double off = 0.0, per = 0.0;
      try {
        if (parts.size() != 2) throw std::invalid_argument("");
        off = std::stod(parts[0]);
        per = std::stod(parts[1]);
      } catch (const std::exception&) {
        throw UsageError(fmt::format("--leakage: '{}' is not 'fit' or OFFSET,PER_PULSE", *l));
      }
      p.fit_leakage = false;
      p.leakage_offset = off;
      p.leakage_per_pulse = per;
    }
  }
  if (const auto w = o.value("--weighting")) {
    if (*w == "ones") {
      p.weighting = DistanceWeighting::kOnes;
    } else if (*w == "inverse-variance") {
      p.weighting = DistanceWeighting::kInverseVariance;
    } else {
      throw UsageError(fmt::format("--weighting: '{}' is not ones or inverse-variance", *w));
    }
  }
  if (o.flag("--no-temperature")) p.fit_temperature = false;
  p.temperature_reference_c = o.number("--temperature-reference", p.temperature_reference_c);
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

std::string summary_json(const ReportContext& c) {
  const auto& r = *c.result;
  const auto& p = *c.params;
  std::string j = "{\n";
  j += fmt::format("  \"command\": {},\n  \"data\": {},\n  \"model\": {},\n", json_string(c.command),
                   json_string(c.data_path), json_string(c.model_path));
  j += fmt::format("  \"rows\": {},\n  \"used\": {},\n", c.data->size(), c.used);
  j += fmt::format("  \"selection\": {},\n  \"grouping\": {},\n  \"groups\": {},\n  \"holdout_groups\": {},\n",
                   json_string(p.declared.selection == ReadoutSelection::kDriver ? "driver" : "all"),
                   json_string(std::string(to_string(r.grouping))), r.groups, r.holdout_groups);
  j += fmt::format("  \"heldout_readouts\": {},\n", r.heldout_eval_rows.size());
  j += fmt::format("  \"rmse_before_m\": {},\n  \"rmse_after_m\": {},\n", json_number(r.rmse_before_m),
                   json_number(r.rmse_after_m));
  j += "  \"effects\": [";
  for (std::size_t k = 0; k < r.effects.size(); ++k) {
    const auto& e = r.effects[k];
    j += fmt::format(
        "{}\n    {{\"covariate\": {}, \"form\": {}, \"rmse_before_m\": {}, \"rmse_after_m\": {}, "
        "\"cv_rmse_before_m\": {}, \"cv_rmse_after_m\": {}, \"gain\": {}, \"z\": {}, \"written\": {}, \"reading\": "
        "{}}}",
        k ? "," : "", json_string(e.covariate), json_string(std::string(to_string(e.form))),
        json_number(e.rmse_before_m), json_number(e.rmse_after_m), json_number(e.cv_rmse_before_m),
        json_number(e.cv_rmse_after_m), json_number(e.gain), json_number(e.z), e.written ? "true" : "false",
        json_string(e.reading));
  }
  j += r.effects.empty() ? "],\n" : "\n  ],\n";
  j += fmt::format(
      "  \"acceptance\": {{\"folds\": {}, \"alpha\": {}, \"z_threshold\": {}, \"min_relative_gain\": {}, "
      "\"max_terms\": {}}},\n",
      p.folds, json_number(p.alpha), json_number(r.z_threshold), json_number(p.min_relative_gain), p.max_terms);
  j += "  \"candidates\": [";
  for (std::size_t k = 0; k < r.candidates.size(); ++k) j += (k ? ", " : "") + json_string(r.candidates[k]);
  j += "],\n  \"rounds\": [";
  for (std::size_t k = 0; k < r.rounds.size(); ++k) {
    j += k ? ",\n    [" : "\n    [";
    for (std::size_t i = 0; i < r.rounds[k].size(); ++i) {
      const auto& s = r.rounds[k][i];
      j += fmt::format(
          "{}\n      {{\"covariate\": {}, \"form\": {}, \"cv_rmse_m\": {}, \"gain\": {}, \"z\": {}, "
          "\"passes\": {}}}",
          i ? "," : "", json_string(s.covariate), json_string(std::string(to_string(s.form))), json_number(s.cv_rmse_m),
          json_number(s.gain), json_number(s.z), s.passes ? "true" : "false");
    }
    j += "\n    ]";
  }
  j += r.rounds.empty() ? "],\n" : "\n  ],\n";
  j += "  \"rejected_on_holdout\": [";
  for (std::size_t k = 0; k < r.rejected_on_holdout.size(); ++k) {
    j += fmt::format("{}{{\"covariate\": {}, \"form\": {}}}", k ? ", " : "",
                     json_string(r.rejected_on_holdout[k].covariate),
                     json_string(std::string(to_string(r.rejected_on_holdout[k].form))));
  }
  j += "],\n  \"notes\": [";
  std::vector<std::string> notes = r.notes;
  notes.insert(notes.end(), c.fit_notes.begin(), c.fit_notes.end());
  notes = unique(std::move(notes));
  for (std::size_t k = 0; k < notes.size(); ++k) j += (k ? ",\n    " : "\n    ") + json_string(notes[k]);
  j += notes.empty() ? "]\n" : "\n  ]\n";
  j += "}\n";
  return j;
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

int cmd_fit(const std::vector<std::string>& argv, std::ostream& out, std::ostream& err, const CalibToolEnv& env) {
  std::vector<std::string> valued = kFitValued;
  valued.insert(valued.end(), kLoopValued.begin(), kLoopValued.end());
  const Options o(argv, valued, {"--discover", "--no-temperature", "--json"});
  if (o.positional().size() != 1) throw UsageError("fit needs exactly one DATA.csv");
  const auto output = o.value("-o") ? o.value("-o") : o.value("--output");
  if (!output) throw UsageError("fit needs -o CALIB.yaml");
  DiscoveryParams p;
  apply_fit_options(o, p.declared);
  apply_loop_options(o, p);
  const bool discover = o.flag("--discover");
  const auto report = o.value("--report");
  const std::string data_path = o.positional()[0];
  // Every output checked before the work (never the input, a link or a device)
  // and replaced only when all of them are made: the model last.
  files::AtomicFile output_file(*output, {.inputs = {data_path}, .what = "calibration"});
  std::optional<ReportFiles> report_files;
  if (report) report_files = open_report(*report, {data_path, *output});
  const auto data = read_calibration_csv(data_path);

  // The declared fit on every row: what is written without --discover, and the in-sample figures.
  const auto declared = fit_declared_model(data, p.declared);
  if (!declared.ok) {
    err << fmt::format("tinyline calib fit: error: {}: {}\n", data_path, declared.reason);
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
  if (discover || report) {
    DiscoveryParams lp = p;
    if (!discover) lp.max_terms = 0;  // the held-out split for the report, no terms
    loop = discover_effects(data, lp);
    if (!loop->ok) {
      err << fmt::format("tinyline calib fit: error: {}: {}\n", data_path, loop->reason);
      return 1;
    }
    print_summary(out, *loop);
    model = loop->model;
  }
  // The per-pixel range SD the driver publishes (section 3.5); in the YAML, not printed.
  model.impl().noise = fit_noise_law(model, data);
  if (const std::string why = unwritable(model, declared.rmse_m, *output); !why.empty()) {
    err << fmt::format("tinyline calib fit: error: {}: {}\n", data_path, why);
    return 1;
  }
  output_file.write(model.to_yaml());
  if (report) {
    ReportContext c;
    c.command = "fit";
    c.data_path = data_path;
    c.model_path = *output;
    c.data = &data;
    c.params = &p;
    c.result = &*loop;
    c.covariate_model = &loop->train_before;
    c.final_model = &model;
    c.used = declared.used;
    c.fit_notes = declared.notes;
    write_report(c, *report_files, env, err);
  }
  output_file.commit();
  out << fmt::format("wrote {}\n", *output);
  if (report) out << fmt::format("wrote {}/report.md\n", *report);
  if (o.flag("--json") && loop) {
    ReportContext c;
    c.command = "fit";
    c.data_path = data_path;
    c.model_path = *output;
    c.data = &data;
    c.params = &p;
    c.result = &*loop;
    c.used = declared.used;
    out << summary_json(c);
  }
  return 0;
}

int cmd_diagnose(const std::vector<std::string>& argv, std::ostream& out, std::ostream& err, const CalibToolEnv& env) {
  std::vector<std::string> valued = {"--calib", "--report"};
  valued.insert(valued.end(), kLoopValued.begin(), kLoopValued.end());
  const Options o(argv, valued, {"--json"});
  if (o.positional().size() != 1) throw UsageError("diagnose needs exactly one DATA.csv");
  const auto calib = o.value("--calib");
  if (!calib) throw UsageError("diagnose needs --calib CALIB.yaml");
  const auto report = o.value("--report");
  if (!report) throw UsageError("diagnose needs --report DIR");
  DiscoveryParams p;
  apply_loop_options(o, p);
  auto report_files = open_report(*report, {o.positional()[0], *calib});
  const auto model = CalibrationModel::load(*calib);
  p.declared.validity = model.validity();
  const std::string data_path = o.positional()[0];
  const auto data = read_calibration_csv(data_path);
  const auto r = diagnose_model(model, data, p);
  if (!r.ok) {
    err << fmt::format("tinyline calib diagnose: error: {}: {}\n", data_path, r.reason);
    return 1;
  }
  print_summary(out, r);
  ReportContext c;
  c.command = "diagnose";
  c.data_path = data_path;
  c.model_path = *calib;
  c.data = &data;
  c.params = &p;
  c.result = &r;
  c.covariate_model = &model;
  c.final_model = &model;
  c.used = r.train_rows.size() + r.heldout_eval_rows.size();
  write_report(c, report_files, env, err);
  out << fmt::format("wrote {}/report.md\n", *report);
  if (o.flag("--json")) out << summary_json(c);
  return 0;
}

int cmd_eval(const std::vector<std::string>& argv, std::ostream& out, std::ostream& err) {
  const Options o(argv, {"--calib", "--select"}, {});
  if (o.positional().size() != 1) throw UsageError("eval needs exactly one DATA.csv");
  const auto calib = o.value("--calib");
  if (!calib) throw UsageError("eval needs --calib CALIB.yaml");
  ReadoutSelection sel = ReadoutSelection::kDriver;
  if (const auto s = o.value("--select")) {
    if (*s == "all") {
      sel = ReadoutSelection::kAll;
    } else if (*s != "driver") {
      throw UsageError(fmt::format("--select: '{}' is not driver or all", *s));
    }
  }
  const auto model = CalibrationModel::load(*calib);
  // A term on a lagged temperature needs that column: derived from the data's own temperatures.
  const auto data = with_derived_covariates(read_calibration_csv(o.positional()[0]), model.extra_covariates());
  const auto s = evaluate_model(model, data, {}, sel);
  if (s.n == 0) {
    err << fmt::format(
        "tinyline calib eval: error: {}: the calibration gives no distance for any read-out ({} "
        "saturated, {} too dark, {} outside its ratio range, {} missing a covariate)\n",
        o.positional()[0], s.saturated, s.too_dark, s.out_of_range, s.missing_covariate);
    return 1;
  }
  out << fmt::format("{{\"n\": {}, \"rmse_m\": {}, \"bias_m\": {}, \"p95_abs_m\": {}}}\n", s.n, json_number(s.rmse_m),
                     json_number(s.bias_m), json_number(s.p95_abs_m));
  if (s.out_of_range || s.missing_covariate) {
    err << fmt::format("note: left out {} read-outs outside the calibrated ratio range and {} missing a covariate\n",
                       s.out_of_range, s.missing_covariate);
  }
  return 0;
}

int cmd_collect(const std::vector<std::string>& argv, std::ostream& out, std::ostream& err) {
  const Options o(argv,
                  {"-o", "--output", "--raw-topic", "--truth-topic", "--sensor", "--max-gap", "--pixel-step",
                   "--positions", "--focal-mm", "--pixels"},
                  {"--keep-mixed", "--incidence"});
  if (o.positional().size() != 1) throw UsageError("collect needs exactly one BAG");
  const auto output = o.value("-o") ? o.value("-o") : o.value("--output");
  if (!output) throw UsageError("collect needs -o DATA.csv");
  CollectParams p;
  p.raw_topic = o.value("--raw-topic").value_or("");
  p.truth_topic = o.value("--truth-topic").value_or("");
  p.sensor = o.value("--sensor").value_or("");
  p.max_pair_gap_s = o.number("--max-gap", p.max_pair_gap_s);
  if (p.max_pair_gap_s < 0.0) throw UsageError("--max-gap must not be negative");
  p.pixel_step = o.integer("--pixel-step", p.pixel_step, 1, 256);
  p.keep_mixed = o.flag("--keep-mixed");
  p.incidence_column = o.flag("--incidence");
  p.positions_csv = o.value("--positions").value_or("");
  p.focal_mm = o.number("--focal-mm", p.focal_mm);
  if (const auto px = o.value("--pixels")) {
    const auto dash = px->find('-');
    try {
      if (dash == std::string::npos) throw std::invalid_argument("");
      std::size_t used_from = 0, used_to = 0;
      p.pixel_from = std::stoi(px->substr(0, dash), &used_from);
      p.pixel_to = std::stoi(px->substr(dash + 1), &used_to);
      if (used_from != dash || used_to != px->size() - dash - 1) throw std::invalid_argument("");
    } catch (const std::exception&) {
      throw UsageError(fmt::format("--pixels: '{}' is not FROM-TO", *px));
    }
    if (p.pixel_from < 0 || p.pixel_to < p.pixel_from || p.pixel_to > 271)
      throw UsageError("--pixels: expected 0 <= FROM <= TO <= 271");
  }
  files::AtomicFile output_file(*output, {.inputs = {o.positional()[0], p.positions_csv}, .what = "data file"});
  const auto r = collect_calibration_data(o.positional()[0], p);
  for (const auto& n : r.notes) err << "note: " << n << "\n";
  if (!r.ok) {
    err << fmt::format("tinyline calib collect: error: {}\n", r.reason);
    return 1;
  }
  std::ostringstream csv;
  write_calibration_csv(r.data, csv);
  output_file.write(csv.str());
  output_file.commit();
  std::size_t materials = r.data.materials.size();
  if (p.positions_csv.empty()) {
    out << fmt::format("{}: {} raw scans on {}, {} truths on {}, {} paired\n", o.positional()[0], r.raw_scans,
                       r.raw_topic, r.truths, r.truth_topic, r.paired);
  } else {
    out << fmt::format("{}: {} raw scans on {}, {} at a logged rail position, {} between positions\n",
                       o.positional()[0], r.raw_scans, r.raw_topic, r.paired, r.between_positions);
  }
  out << fmt::format("pixels left out per set: {} dark, {} without a range, {} unlit, {} mixed (totals over sets)\n",
                     r.dark_pixels, r.no_range, r.unlit, r.mixed);
  out << fmt::format("wrote {} rows ({} material{}) to {}\n", r.data.size(), materials, materials == 1 ? "" : "s",
                     *output);
  return 0;
}

}  // namespace

int run_calib_command(const std::vector<std::string>& args, std::ostream& out, std::ostream& err,
                      const CalibToolEnv& env) {
  if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    (args.empty() ? err : out) << kUsage;
    return args.empty() ? 2 : 0;
  }
  const std::string& sub = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (std::find(rest.begin(), rest.end(), "--help") != rest.end() ||
      std::find(rest.begin(), rest.end(), "-h") != rest.end()) {
    out << kUsage;
    return 0;
  }
  try {
    if (sub == "fit") return cmd_fit(rest, out, err, env);
    if (sub == "diagnose") return cmd_diagnose(rest, out, err, env);
    if (sub == "eval") return cmd_eval(rest, out, err);
    if (sub == "collect") return cmd_collect(rest, out, err);
    if (sub == "measured") return tool::cmd_measured(rest, out, err, env);
    err << fmt::format("tinyline calib: unknown command '{}'\n\n{}", sub, kUsage);
    return 2;
  } catch (const UsageError& e) {
    err << fmt::format("tinyline calib {}: {}\n\n{}", sub, e.what(), kUsage);
    return 2;
  } catch (const std::exception& e) {
    err << fmt::format("tinyline calib {}: error: {}\n", sub, e.what());
    return 1;
  }
}

}  // namespace tinyline::tiny_laser_calibration
