// SPDX-License-Identifier: Apache-2.0
// laser_clustering_eval: the evaluation of docs/laser_clustering.md.
//
//   laser_clustering_eval [--trials 200] [--seed 1] [--out out/laser_clustering_eval]
//                         [--cases random_offset,recognition_error,stick,wrench] [--pictures 4]
//                         [--failure-pictures 4] [--ablation] [--raw-pulses 10,20,50,120,300] [--rescans 2]
//                         [--no-tomato-look]
//   laser_clustering_eval --write-calibration FILE [--raw-pulses ...]
//
// Prints the Markdown tables of the doc; writes summary.json, one CSV per
// case with every trial, and the scans of the first --pictures trials of
// each case (scans/*.csv) for scripts/plots/clustering_scans.py.
#include <cmath>
#include <system_error>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <algorithm>
#include <iostream>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>
#include <tinyline/common/seeds.hpp>

#include "harness.hpp"
#include "scanner.hpp"

namespace cli = tinyline::cli;

namespace ev = tinyline::laser_clustering::eval;
namespace sim = tinyline::sim;
namespace lc = tinyline::laser_clustering;
namespace fs = std::filesystem;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

struct Args {
  int trials = 200;
  std::uint64_t seed = 1;
  fs::path out = "out/laser_clustering_eval";
  std::set<std::string> cases{"random_offset", "recognition_error", "stick", "wrench"};
  int pictures = 4;          ///< scans of the first K trials of each case
  int failure_pictures = 4;  ///< and of the first K truss trials that did not align
  /// Raw-mode schedule of both sensors [pulses]: the nearest to close work a
  /// real sensor can run (the wire sets pulses in tens, tiny_laser_driver/protocol.hpp).
  std::vector<int> raw_pulses = {10, 20, 50, 120, 300};
  int rescans = 2;                ///< truss cases: scans after the first move (TrussEvalOptions::rescans)
  bool tomato_look = true;        ///< TrussEvalOptions::tomato_look
  std::string write_calibration;  ///< write the gripper sensor's calibration here and stop
  bool ablation = false;          ///< also the truss cases under earlier parameter sets and a one-stage baseline
  bool tuning = false;            ///< the run chooses parameters: only tuning seeds (common/seeds.hpp)
  ev::TrussOptions scene;         ///< truss cases' scene options (--scene-set)
  std::string scene_label;        ///< ... as given, for the seeds' label
};

// Fills `a` from the command line; the exit code when the program stops there.
std::optional<int> parse(int argc, char** argv, Args& a) {
  cli::App app{
      "The evaluation of docs/laser_clustering.md on the simulated sensor: prints the Markdown tables, "
      "writes summary.json, one CSV per case and the scans of the first trials.",
      "laser_clustering_eval"};
  app.add_option("--trials", a.trials, "trials per case")->check(cli::range(1, 1 << 30))->capture_default_str();
  app.add_option("--seed", a.seed, "seed of the first trial")->check(cli::non_negative())->capture_default_str();
  app.add_option("--out", a.out, "output directory")->capture_default_str();
  std::vector<std::string> cases(a.cases.begin(), a.cases.end());
  app.add_option("--cases", cases, "comma-separated cases")
      ->delimiter(',')
      ->check(cli::one_of({"random_offset", "recognition_error", "stick", "wrench"}))
      ->capture_default_str();
  app.add_option("--pictures", a.pictures, "scans of the first K trials of each case")
      ->check(cli::non_negative())
      ->capture_default_str();
  app.add_option("--failure-pictures", a.failure_pictures, "and of the first K truss trials that did not align")
      ->check(cli::non_negative())
      ->capture_default_str();
  app.add_flag("--tuning", a.tuning,
               "this run is for choosing parameters: refuse any seed that is not a tuning seed (docs/evaluation.md)");
  app.add_flag("--ablation", a.ablation, "also the truss cases under earlier parameter sets and a one-stage baseline");
  app.add_option("--raw-pulses", a.raw_pulses, "raw-mode read-out schedule of both sensors [pulses], comma-separated")
      ->delimiter(',')
      ->check(cli::positive())
      ->capture_default_str();
  app.add_option("--rescans", a.rescans, "truss cases: scans after the first move")
      ->check(cli::non_negative())
      ->capture_default_str();
  bool no_tomato_look = false;
  app.add_flag("--no-tomato-look", no_tomato_look, "no look through the tomatoes before a blind move");
  app.add_option("--write-calibration", a.write_calibration,
                 "write the gripper sensor's calibration to FILE and stop (with --raw-pulses)");
  std::vector<std::string> scene_sets;
  app.add_option("--scene-set", scene_sets,
                 "truss cases' scene option key=value: max_tilt_deg (default 15), stem_bow_m "
                 "(default 0), repeatable")
      ->check(cli::Validator(
          [&a](std::string& kv) -> std::string {
            const auto eq = kv.find('=');
            if (eq == std::string::npos) return "--scene-set wants key=value, got '" + kv + "'";
            a.scene_label += ", scene " + kv;
            return ev::set_truss_option(a.scene, kv.substr(0, eq), kv.substr(eq + 1));
          },
          "KEY=VALUE"));
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return rc;
  a.cases = std::set<std::string>(cases.begin(), cases.end());
  a.tomato_look = !no_tomato_look;
  if (a.tuning) {
    try {
      tinyline::common::seeds::require_tuning(
          tinyline::common::seeds::kLaserClustering,
          tinyline::common::seeds::seed_run(a.seed, static_cast<std::uint64_t>(a.trials)));
    } catch (const std::invalid_argument& e) {
      std::cerr << "laser_clustering_eval: " << e.what() << "\n";
      return 2;
    }
  }
  return std::nullopt;
}

std::string rate(const ev::Rate& r) {
  return fmt::format("{}/{} = {:.1f} % [{:.1f}, {:.1f}]", r.k, r.n, 100.0 * r.p, 100.0 * r.lo, 100.0 * r.hi);
}
std::string rate_json(const ev::Rate& r) {
  return fmt::format(R"({{"k": {}, "n": {}, "p": {:.6f}, "lo": {:.6f}, "hi": {:.6f}}})", r.k, r.n, r.p, r.lo, r.hi);
}

// One scan with everything the pictures show.
void write_scan(const fs::path& path, const ev::SimulatedScan& s, const std::vector<int>& labels,
                const std::vector<double>& filtered, const std::vector<std::string>& kind, int chosen_label) {
  tinyline::files::AtomicStream f(path.string());
  f << "pixel,angle_rad,range_m,filtered_m,reflectance,label,chosen,truth\n";
  for (std::size_t i = 0; i < s.scan.size(); ++i) {
    f << fmt::format("{},{:.6f},{:.5f},{:.5f},{:.4f},{},{},{}\n", i, s.scan.angle_rad[i], s.scan.range_m[i],
                     filtered.empty() ? std::nan("") : filtered[i],
                     s.scan.reflectance.empty() ? std::nan("") : s.scan.reflectance[i], labels[i],
                     labels[i] >= 0 && labels[i] == chosen_label ? 1 : 0, kind[i]);
  }
  f.commit();
}

// What each pixel's central ray hits in a truss scene ("target", "tomato", ...).
std::vector<std::string> truth_kinds(const ev::TrussScene& scene, const ev::SimulatedScan& s) {
  std::vector<std::string> kind(s.scan.size());
  for (std::size_t i = 0; i < kind.size(); ++i) kind[i] = ev::object_kind(scene, s.truth_object[i]);
  return kind;
}

// The harvesting gripper's sensor works at 8-25 cm: the wide 3.6 mm lens;
// the tool-grasping tasks at 20-35 cm: the 8 mm lens. Both with a raw-mode
// schedule short enough for close range (the default 20..700 pulses
// saturates every pixel nearer than about 20 cm).
struct ScannerOptions {
  ev::SimScannerOptions gripper, tools;
};

ScannerOptions scanner_options(const Args& args) {
  ScannerOptions s;
  s.gripper.sensor_config = "tiny_tof_3p6mm.yaml";
  s.tools.sensor_config = "tiny_tof_8mm.yaml";
  for (auto* o : {&s.gripper, &s.tools}) {
    o->raw_pulses = args.raw_pulses;
    o->calibration_max_m = 0.6;
    o->calibration_step_m = 0.01;
    o->calibration_sets = 3;
  }
  return s;
}

void write_calibration(const Args& args, const ev::SimScannerOptions& gripper) {
  const auto c = ev::write_sim_calibration(gripper, args.write_calibration);
  std::cout << fmt::format(
      "wrote {}: {} sensor, raw pulses {}, rail 5-{:.0f} cm every {:.0f} mm, in-sample RMSE {:.1f} mm; "
      "white paper's reflectance figure {:.1f} (2 %: {:.1f})\n",
      args.write_calibration, gripper.sensor_config, fmt::join(gripper.raw_pulses, "/"),
      gripper.calibration_max_m * 100, gripper.calibration_step_m * 1000, c.rmse_m * 1e3, c.white_reflectance,
      0.02 * c.white_reflectance);
}

/// What every case's step needs: the options, the scanners, the seeds' label
/// (on every table) and summary.json.
struct Evaluation {
  const Args& args;
  std::unique_ptr<ev::Scanner> truss_scanner, tool_scanner;
  std::string seeds;
  std::ostringstream json;  ///< summary.json, written when the run ends

  ev::TrussResult truss(ev::TrussCase c, const ev::TrussEvalOptions& o) const {
    return ev::run_truss_case(c, *truss_scanner, args.trials, args.seed, o);
  }
};

/// The scanners the chosen cases need, the run's description printed and
/// summary.json opened.
void open_evaluation(Evaluation& e, const ScannerOptions& so) {
  const Args& args = e.args;
  const bool trusses = args.cases.count("random_offset") || args.cases.count("recognition_error");
  const bool metal = args.cases.count("stick") || args.cases.count("wrench");
  e.truss_scanner = trusses ? ev::make_sim_scanner(so.gripper) : nullptr;
  e.tool_scanner = metal ? ev::make_sim_scanner(so.tools) : nullptr;
  std::cout << "# laser_clustering evaluation\n\n";
  if (e.truss_scanner) std::cout << "trusses: " << e.truss_scanner->describe() << "\n\n";
  if (e.tool_scanner) std::cout << "stick and wrench: " << e.tool_scanner->describe() << "\n\n";
  if (trusses) {
    std::cout << "truss cases: closed loop with up to " << args.rescans << " re-scan(s) after a move, "
              << (args.tomato_look ? "with" : "without") << " the tomato look\n\n";
  }
  // Every figure below comes from these seeds: the label goes on the run and on each table.
  e.seeds = tinyline::common::seeds::describe(
      tinyline::common::seeds::kLaserClustering,
      tinyline::common::seeds::seed_run(args.seed, static_cast<std::uint64_t>(args.trials)));
  e.seeds += args.scene_label;
  std::cout << "trials per case: " << args.trials << ", " << e.seeds << "\n\n";
  e.json << "{\n  \"truss_scanner\": \"" << (e.truss_scanner ? e.truss_scanner->describe() : "")
         << "\",\n  \"tool_scanner\": \"" << (e.tool_scanner ? e.tool_scanner->describe() : "")
         << "\",\n  \"trials\": " << args.trials << ",\n  \"seed\": " << args.seed << ",\n  \"seeds\": \"" << e.seeds
         << "\"";
}

/// A truss case's trials: every trial a CSV row; the scans of the first
/// --pictures trials, of the first --failure-pictures that did not align and
/// of the first --pictures looks through the tomatoes.
struct TrussRecorder {
  const Args& args;
  std::string name;
  tinyline::files::AtomicStream csv;
  int pictures = 0, failures = 0, looks = 0;

  TrussRecorder(const Args& a, std::string case_name)
      : args(a), name(std::move(case_name)), csv((args.out / ("trials_" + name + ".csv")).string()) {
    csv << "seed,verdict,outcome,chosen,lateral_error_m,confidence,target_visible,neighbour_nearer,looked,registered\n";
  }

  void trial(const ev::TrussTrial& t, const ev::TrussScene& scene, const ev::SimulatedScan& s,
             const lc::TwoStageResult& o, const lc::PedicelDetection& d) {
    csv << fmt::format("{},{},{},{},{:.5f},{:.3f},{},{},{},{}\n", t.seed, ev::to_string(t.verdict),
                       lc::to_string(t.outcome), t.chosen_kind, t.lateral_error_m, t.confidence,
                       t.target_visible ? 1 : 0, t.neighbour_nearer ? 1 : 0, t.looked ? 1 : 0, t.registered ? 1 : 0);
    const bool failure = t.verdict != ev::Verdict::kAligned && failures < args.failure_pictures;
    if (pictures >= args.pictures && !failure) return;
    ++(failure ? failures : pictures);
    const std::vector<std::string> kind = truth_kinds(scene, s);
    const int chosen = d.cluster >= 0 ? o.clusters[static_cast<std::size_t>(d.cluster)].id : -1;
    write_scan(args.out / "scans" / fmt::format("{}_{}_{}.csv", name, t.seed, ev::to_string(t.verdict)), s, o.labels,
               o.smoothed_range_m, kind, chosen);
  }

  void look(std::uint64_t seed, const ev::TrussScene& scene, const ev::SimulatedScan& look,
            const std::vector<lc::ExpectedTomato>& tomatoes, const lc::TomatoRegistration& reg) {
    if (looks >= args.pictures) return;
    ++looks;
    const std::vector<std::string> kind = truth_kinds(scene, look);
    const std::vector<int> none(look.scan.size(), lc::kNoise);
    const std::string stem = fmt::format("look_{}_{}", name, seed);
    write_scan(args.out / "scans" / (stem + ".csv"), look, none, {}, kind, -1);
    tinyline::files::AtomicStream t((args.out / "scans" / (stem + "_tomatoes.csv")).string());
    t << "expected_x_m,expected_z_m,height_m,radius_m,registered,shift_x_m,shift_z_m\n";
    for (const auto& e : tomatoes) {
      t << fmt::format("{:.5f},{:.5f},{:.5f},{:.5f},{},{:.5f},{:.5f}\n", e.centre_m.x(), e.centre_m.z(), e.centre_m.y(),
                       e.radius_m, reg.status.ok() ? 1 : 0, reg.shift_xz_m.x(), reg.shift_xz_m.y());
    }
    t.commit();
  }
};

void truss_case(Evaluation& e, const std::string& name, ev::TrussCase c) {
  const Args& args = e.args;
  TrussRecorder rec(args, name);
  ev::TrussEvalOptions options;
  options.scene = args.scene;
  options.rescans = args.rescans;
  options.tomato_look = args.tomato_look;
  const auto r = ev::run_truss_case(
      c, *e.truss_scanner, args.trials, args.seed, options, [&rec](const auto&... trial) { rec.trial(trial...); },
      [&rec](const auto&... look) { rec.look(look...); });
  rec.csv.commit();
  std::cout << "## " << name << " (" << e.seeds << ")\n\n| verdict | rate [95 % CI] |\n|---|---|\n"
            << "| aligned | " << rate(r.aligned) << " |\n| wrong | " << rate(r.wrong) << " |\n| out of view | "
            << rate(r.out_of_view) << " |\n| missed (in view, no move) | " << rate(r.missed) << " |\n"
            << "| a neighbour pedicel nearer the expected point than the target (ambiguous) | " << rate(r.ambiguous)
            << " |\n| aligned among the unambiguous trials | " << rate(r.aligned_unambiguous) << " |\n\n";
  e.json << fmt::format(
      ",\n  \"{}\": {{\"aligned\": {}, \"wrong\": {}, \"out_of_view\": {}, \"missed\": {}, \"ambiguous\": {}, "
      "\"aligned_unambiguous\": {}}}",
      name, rate_json(r.aligned), rate_json(r.wrong), rate_json(r.out_of_view), rate_json(r.missed),
      rate_json(r.ambiguous), rate_json(r.aligned_unambiguous));
}

void truss_cases(Evaluation& e) {
  for (const auto& [name, c] : {std::pair{std::string("random_offset"), ev::TrussCase::kRandomOffset},
                                std::pair{std::string("recognition_error"), ev::TrussCase::kRecognitionError}}) {
    if (e.args.cases.count(name)) truss_case(e, name, c);
  }
}

struct ClusteringVariant {
  const char* name;
  lc::TwoStageParams p;
};

/// The parameter sets the two-stage clustering went through (docs), and the
/// one-stage baseline (a single small-eps DBSCAN: no groups, no edge filter,
/// no smoothing).
std::vector<ClusteringVariant> clustering_history() {
  std::vector<ClusteringVariant> variants;
  lc::TwoStageParams v0;  // first defaults, set on the synthetic unit-test scans
  v0.groups = {0.025, 4};
  v0.edge.step_m = 0.006;
  v0.edge.smooth_step_m = 0.006;
  v0.edge.mixed_step_m = 1e9;
  variants.push_back({"v0: first defaults (synthetic scans)", v0});
  lc::TwoStageParams v1 = v0;  // thresholds from the sensor's noise
  v1.groups = {0.03, 4};
  v1.edge.step_m = 0.018;
  v1.edge.smooth_step_m = 0.018;
  variants.push_back({"v1: edge threshold from the range noise", v1});
  variants.push_back({"v2 (defaults): + mixed pixels inside runs, smoothing limit", lc::TwoStageParams{}});
  lc::TwoStageParams one;
  one.groups = {0.008, 2};
  one.edge.edge_width_px = 0;
  one.edge.mixed_step_m = 1e9;
  one.edge.smooth_half_width_px = 0;
  variants.push_back({"one-stage baseline: DBSCAN 8 mm / 2 only", one});
  return variants;
}

/// The tomato look against the pedicel plane alone (everything else the
/// default): the before of the look.
void ablation_without_look(Evaluation& e) {
  ev::TrussEvalOptions no_look;
  no_look.tomato_look = false;
  const auto a = e.truss(ev::TrussCase::kRandomOffset, no_look);
  const auto b = e.truss(ev::TrussCase::kRecognitionError, no_look);
  std::cout << "without the tomato look (the pedicel plane alone): random offset aligned " << rate(a.aligned)
            << ", wrong " << rate(a.wrong) << "; recognition error aligned " << rate(b.aligned) << ", wrong "
            << rate(b.wrong) << "\n\n"
            << "(the rows below are the finder's own steps, all without the tomato look)\n\n";
  e.json << fmt::format(
      ",\n  \"without_tomato_look\": {{\"random_offset_aligned\": {}, \"random_offset_wrong\": {}, "
      "\"recognition_error_aligned\": {}}}",
      rate_json(a.aligned), rate_json(a.wrong), rate_json(b.aligned));
}

/// Both truss cases under each clustering of the history, on the same seeds.
void ablation_table(Evaluation& e) {
  const std::vector<ClusteringVariant> variants = clustering_history();
  std::cout << "## ablation (truss cases, " << e.seeds << ")\n\n"
            << "| clustering | random offset: aligned | wrong | recognition error: "
               "aligned | wrong |\n|---|---|---|---|---|\n";
  e.json << ",\n  \"ablation\": [";
  for (std::size_t i = 0; i < variants.size(); ++i) {
    ev::TrussEvalOptions o;
    o.tomato_look = false;  // the finder's own steps, before the tomato look
    o.clustering = variants[i].p;
    o.rescans = e.args.rescans;
    const auto a = e.truss(ev::TrussCase::kRandomOffset, o);
    const auto b = e.truss(ev::TrussCase::kRecognitionError, o);
    std::cout << "| " << variants[i].name << " | " << rate(a.aligned) << " | " << rate(a.wrong) << " | "
              << rate(b.aligned) << " | " << rate(b.wrong) << " |\n";
    e.json << fmt::format(
        "{}\n    {{\"name\": \"{}\", \"random_offset_aligned\": {}, \"recognition_error_aligned\": {}}}", i ? "," : "",
        variants[i].name, rate_json(a.aligned), rate_json(b.aligned));
  }
  e.json << "\n  ]";
}

/// The random-offset case without the vision's truss layout (the nearest
/// pedicel to the throat, the thesis's rule): the before of the layout test.
void ablation_without_layout(Evaluation& e) {
  ev::TrussEvalOptions no_layout;
  no_layout.tomato_look = false;  // the finder's own steps, before the tomato look
  no_layout.use_layout = false;
  no_layout.rescans = e.args.rescans;
  const auto l = e.truss(ev::TrussCase::kRandomOffset, no_layout);
  std::cout << "\nrandom offset without the truss layout (nearest pedicel to the throat): aligned " << rate(l.aligned)
            << ", wrong " << rate(l.wrong) << ", aligned among the unambiguous trials " << rate(l.aligned_unambiguous)
            << "\n";
  e.json << fmt::format(",\n  \"random_offset_no_layout\": {{\"aligned\": {}, \"wrong\": {}}}", rate_json(l.aligned),
                        rate_json(l.wrong));
}

/// The closed loop re-centring on the first choice alone (the runners-up
/// not carried into the re-scans): the before of carrying them.
void ablation_without_runners_up(Evaluation& e) {
  ev::TrussEvalOptions chosen_only;
  chosen_only.tomato_look = false;  // the finder's own steps, before the tomato look
  chosen_only.carry_runners_up = false;
  chosen_only.rescans = e.args.rescans;
  const auto c1 = e.truss(ev::TrussCase::kRandomOffset, chosen_only);
  const auto c2 = e.truss(ev::TrussCase::kRecognitionError, chosen_only);
  std::cout << "\nre-scans without the runners-up (re-centring on the first choice): random offset aligned "
            << rate(c1.aligned) << ", wrong " << rate(c1.wrong) << "; recognition error aligned " << rate(c2.aligned)
            << ", wrong " << rate(c2.wrong) << "\n";
  e.json << fmt::format(
      ",\n  \"rescans_without_runners_up\": {{\"random_offset_aligned\": {}, \"random_offset_wrong\": {}, "
      "\"recognition_error_aligned\": {}}}",
      rate_json(c1.aligned), rate_json(c1.wrong), rate_json(c2.aligned));
}

/// Both truss cases from the first scan alone (no closed loop): the before
/// of the re-scan.
void ablation_first_scan_alone(Evaluation& e) {
  ev::TrussEvalOptions single;
  single.tomato_look = false;  // the finder's own steps, before the tomato look
  single.rescans = 0;
  const auto s1 = e.truss(ev::TrussCase::kRandomOffset, single);
  const auto s2 = e.truss(ev::TrussCase::kRecognitionError, single);
  std::cout << "\nfirst scan alone (no re-scan): random offset aligned " << rate(s1.aligned) << ", wrong "
            << rate(s1.wrong) << "; recognition error aligned " << rate(s2.aligned) << ", wrong " << rate(s2.wrong)
            << "\n";
  e.json << fmt::format(
      ",\n  \"first_scan_alone\": {{\"random_offset_aligned\": {}, \"random_offset_wrong\": {}, "
      "\"recognition_error_aligned\": {}}}",
      rate_json(s1.aligned), rate_json(s1.wrong), rate_json(s2.aligned));
}

/// The recognition-error case as the thesis's robot met it: the nearest
/// pedicel to the throat, without the tomato-based expectation.
void ablation_nearest_pedicel(Evaluation& e) {
  ev::TrussEvalOptions nearest;
  nearest.tomato_look = false;  // the finder's own steps, before the tomato look
  nearest.use_expectation = false;
  nearest.rescans = e.args.rescans;
  const auto n = e.truss(ev::TrussCase::kRecognitionError, nearest);
  std::cout << "\nrecognition error without the tomato-based expectation (nearest pedicel to the throat): aligned "
            << rate(n.aligned) << ", wrong " << rate(n.wrong) << ", missed or out of view "
            << rate(ev::wilson(n.missed.k + n.out_of_view.k, n.missed.n)) << "\n\n";
  e.json << fmt::format(",\n  \"recognition_error_nearest\": {{\"aligned\": {}, \"wrong\": {}}}", rate_json(n.aligned),
                        rate_json(n.wrong));
}

/// The truss cases without each of the finder's steps in turn, on the same held-out seeds.
void ablation(Evaluation& e) {
  ablation_without_look(e);
  ablation_table(e);
  ablation_without_layout(e);
  ablation_without_runners_up(e);
  ablation_first_scan_alone(e);
  ablation_nearest_pedicel(e);
}

/// The scans of a stick trial: what each pixel sees, clustered with and without reflectance.
void write_stick_scans(const Args& args, const std::string& material, const ev::StickTrial& t,
                       const ev::StickScene& scene, const ev::SimulatedScan& s,
                       const lc::ReflectanceClusteringResult& with, const lc::ReflectanceClusteringResult& without) {
  std::vector<std::string> kind(s.scan.size(), "none");
  for (std::size_t i = 0; i < kind.size(); ++i) {
    if (s.truth_object[i] == scene.stick) kind[i] = s.truth_mixed[i] ? "stick_mixed" : "stick";
    if (s.truth_object[i] == scene.panel) kind[i] = s.truth_mixed[i] ? "panel_mixed" : "panel";
  }
  const int bw = with.brightest >= 0 ? with.clusters[static_cast<std::size_t>(with.brightest)].id : -1;
  const std::string stem = fmt::format("stick_{}_{}", material, t.seed);
  write_scan(args.out / "scans" / (stem + "_reflectance.csv"), s, with.labels, {}, kind, bw);
  write_scan(args.out / "scans" / (stem + "_distance.csv"), s, without.labels, {}, kind, -1);
}

/// One stick run (material, gap): its table row and JSON entry; the first
/// two runs' first --pictures trials get their scans written.
void stick_run(Evaluation& e, std::ostream& csv, std::size_t run, const char* material, double gap_m) {
  const Args& args = e.args;
  ev::StickEvalOptions so;
  so.scene.stick_material = material;
  so.scene.front_gap_m = gap_m;
  int pictures = 0;
  const auto r = ev::run_stick_case(
      *e.tool_scanner, args.trials, args.seed, so,
      [&](const ev::StickTrial& t, const ev::StickScene& scene, const ev::SimulatedScan& s,
          const lc::ReflectanceClusteringResult& with, const lc::ReflectanceClusteringResult& without) {
        csv << fmt::format("{},{},{:.4f},{:.4f}\n", so.scene.stick_material, t.seed, t.iou_reflectance,
                           t.iou_distance_only);
        if (run > 1 || pictures >= args.pictures) return;
        ++pictures;
        write_stick_scans(args, so.scene.stick_material, t, scene, s, with, without);
      });
  std::cout << fmt::format("| {} | {:.0f} mm | {} | {} |\n", so.scene.stick_material, so.scene.front_gap_m * 1e3,
                           rate(r.reflectance_correct), rate(r.distance_only_correct));
  e.json << fmt::format(
      "{}\n    {{\"material\": \"{}\", \"front_gap_m\": {}, \"reflectance\": {}, \"distance_only\": {}}}",
      run == 0 ? "" : ",", so.scene.stick_material, so.scene.front_gap_m, rate_json(r.reflectance_correct),
      rate_json(r.distance_only_correct));
}

void stick_case(Evaluation& e) {
  tinyline::files::AtomicStream csv((e.args.out / "trials_stick.csv").string());
  csv << "material,seed,iou_reflectance,iou_distance_only\n";
  std::cout << "## stick (Figure 5.8 B; " << e.seeds << ")\n\n"
            << "| stick | front before the panel | distance and reflectance | distance alone |\n"
               "|---|---:|---|---|\n";
  e.json << ",\n  \"stick\": [";
  // A brushed and a polished metal stick 4 mm before a cardboard panel, and
  // the brushed one at other gaps (where distance alone starts to work).
  const std::vector<std::pair<const char*, double>> runs{{"metal_pan", 0.004}, {"metal_wrench", 0.004},
                                                         {"metal_pan", 0.002}, {"metal_pan", 0.008},
                                                         {"metal_pan", 0.015}, {"metal_pan", 0.03}};
  for (std::size_t run = 0; run < runs.size(); ++run) stick_run(e, csv, run, runs[run].first, runs[run].second);
  csv.commit();
  e.json << "\n  ]";
  std::cout << "\n";
}

void wrench_case(Evaluation& e) {
  const Args& args = e.args;
  tinyline::files::AtomicStream csv((args.out / "trials_wrench.csv").string());
  csv << "seed,outcome,true_pitch_deg,best_pitch_deg,error_deg,step_error_deg\n";
  tinyline::files::AtomicStream sweeps((args.out / "wrench_sweeps.csv").string());
  sweeps << "seed,pitch_deg,reflectance,true_pitch_deg,best_pitch_deg\n";
  int pictures = 0;
  const auto r =
      ev::run_wrench_case(*e.tool_scanner, args.trials, args.seed, {},
                          [&](const ev::WrenchTrial& t, const std::vector<lc::AlignmentSample>& sweep) {
                            csv << fmt::format("{},{},{:.4f},{:.4f},{:.4f},{:.4f}\n", t.seed, lc::to_string(t.outcome),
                                               t.true_pitch_rad / kDeg, t.best_pitch_rad / kDeg, t.error_rad / kDeg,
                                               t.step_error_rad / kDeg);
                            if (pictures++ >= args.pictures) return;
                            for (const auto& s : sweep) {
                              sweeps << fmt::format("{},{:.4f},{:.4f},{:.4f},{:.4f}\n", t.seed, s.pitch_rad / kDeg,
                                                    s.reflectance, t.true_pitch_rad / kDeg, t.best_pitch_rad / kDeg);
                            }
                          });
  csv.commit();
  sweeps.commit();
  std::cout << "## wrench alignment (5.3.2; " << e.seeds << ")\n\n"
            << "| figure | value |\n|---|---|\n"
            << fmt::format("| median pitch error | {:.2f} deg |\n| 90th percentile | {:.2f} deg |\n",
                           r.median_error_deg, r.p90_error_deg)
            << fmt::format("| median error of the brightest step alone (2 deg steps) | {:.2f} deg |\n",
                           r.median_step_error_deg)
            << "| within 1 deg | " << rate(r.within_1deg) << " |\n| peak found | " << rate(r.found) << " |\n\n";
  e.json << fmt::format(
      ",\n  \"wrench\": {{\"median_error_deg\": {:.4f}, \"p90_error_deg\": {:.4f}, \"median_step_error_deg\": {:.4f}, "
      "\"within_1deg\": {}, \"found\": {}}}",
      r.median_error_deg, r.p90_error_deg, r.median_step_error_deg, rate_json(r.within_1deg), rate_json(r.found));
}

}  // namespace

int main(int argc, char** argv) {
  Args parsed;
  if (const auto rc = parse(argc, argv, parsed)) return *rc;
  const Args& args = parsed;
  if (!args.write_calibration.empty()) {  // that file alone: no output folder
    if (!tinyline::files::output_allowed("laser_clustering_eval", args.write_calibration,
                                         tinyline::files::named("calibration")))
      return 1;
    write_calibration(args, scanner_options(args).gripper);
    return 0;
  }
  // The tables checked before the folder is made and any trial runs (the scans are checked as written).
  for (const std::string name : {"summary.json", "trials_random_offset.csv", "trials_recognition_error.csv",
                                 "trials_stick.csv", "trials_wrench.csv", "wrench_sweeps.csv"}) {
    if (!tinyline::files::output_allowed("laser_clustering_eval", (args.out / name).string())) return 1;
  }
  if (std::error_code ec; !fs::create_directories(args.out / "scans", ec) && ec) {
    std::cerr << "laser_clustering_eval: cannot create the output directory " << (args.out / "scans") << ": "
              << ec.message() << "\n";
    return 2;
  }
  const ScannerOptions scanners = scanner_options(args);
  Evaluation e{args, nullptr, nullptr, {}, {}};
  try {
    open_evaluation(e, scanners);
    truss_cases(e);
    if (args.ablation && e.truss_scanner) ablation(e);
    if (args.cases.count("stick")) stick_case(e);
    if (args.cases.count("wrench")) wrench_case(e);
    e.json << "\n}\n";
    tinyline::files::write_atomically((args.out / "summary.json").string(), e.json.view());
  } catch (const tinyline::files::FileError& err) {
    std::cerr << "laser_clustering_eval: " << err.what() << "\n";
    return 1;
  }
  std::cout << "outputs in " << args.out.string() << "\n";
  return 0;
}
