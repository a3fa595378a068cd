// laser_clustering_eval: the evaluation of docs/laser_clustering.md.
//
//   laser_clustering_eval [--trials 200] [--seed 1] [--out out/laser_clustering_eval]
//                         [--cases random_offset,recognition_error,stick,wrench] [--pictures 4]
//
// Prints the Markdown tables of the doc; writes summary.json, one CSV per
// case with every trial, and the scans of the first --pictures trials of
// each case (scans/*.csv) for scripts/plots/clustering_scans.py.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <algorithm>
#include <iostream>
#include <numbers>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "harness.hpp"
#include "sim_scanner.hpp"

namespace ev = tinyline::laser_clustering::eval;
namespace lc = tinyline::laser_clustering;
namespace fs = std::filesystem;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

struct Args {
  int trials = 200;
  std::uint64_t seed = 1;
  fs::path out = "out/laser_clustering_eval";
  std::set<std::string> cases{"random_offset", "recognition_error", "stick", "wrench"};
  int pictures = 4;
};

[[noreturn]] void usage(const std::string& why) {
  std::cerr << "laser_clustering_eval: " << why
            << "\nusage: laser_clustering_eval [--trials N] [--seed S] [--out DIR] [--cases a,b,...] [--pictures K]\n"
               "cases: random_offset, recognition_error, stick, wrench\n";
  std::exit(2);
}

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage("missing value after " + k);
      return argv[++i];
    };
    auto integer = [&](const std::string& v, long lo) {
      char* end = nullptr;
      const long x = std::strtol(v.c_str(), &end, 10);
      if (end == v.c_str() || *end != '\0' || x < lo) usage(fmt::format("{} needs an integer >= {}, got '{}'", k, lo, v));
      return x;
    };
    if (k == "--trials") {
      a.trials = static_cast<int>(integer(value(), 1));
    } else if (k == "--seed") {
      a.seed = static_cast<std::uint64_t>(integer(value(), 0));
    } else if (k == "--out") {
      a.out = value();
    } else if (k == "--pictures") {
      a.pictures = static_cast<int>(integer(value(), 0));
    } else if (k == "--cases") {
      a.cases.clear();
      std::stringstream ss(value());
      for (std::string c; std::getline(ss, c, ',');) {
        if (c != "random_offset" && c != "recognition_error" && c != "stick" && c != "wrench") usage("unknown case '" + c + "'");
        a.cases.insert(c);
      }
    } else {
      usage("unknown argument '" + k + "'");
    }
  }
  return a;
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
  std::ofstream f(path);
  f << "pixel,angle_rad,range_m,filtered_m,reflectance,label,chosen,truth\n";
  for (std::size_t i = 0; i < s.scan.size(); ++i) {
    f << fmt::format("{},{:.6f},{:.5f},{:.5f},{:.4f},{},{},{}\n", i, s.scan.angle_rad[i], s.scan.range_m[i],
                     filtered.empty() ? std::nan("") : filtered[i],
                     s.scan.reflectance.empty() ? std::nan("") : s.scan.reflectance[i], labels[i],
                     labels[i] >= 0 && labels[i] == chosen_label ? 1 : 0, kind[i]);
  }
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  fs::create_directories(args.out / "scans");
  auto scanner = ev::make_sim_scanner();
  std::cout << "# laser_clustering evaluation\n\nscanner: " << scanner->describe() << "\ntrials per case: " << args.trials
            << ", seeds " << args.seed << " .. " << args.seed + static_cast<std::uint64_t>(args.trials) - 1 << "\n\n";
  std::ofstream json(args.out / "summary.json");
  json << "{\n  \"scanner\": \"" << scanner->describe() << "\",\n  \"trials\": " << args.trials << ",\n  \"seed\": " << args.seed;

  for (const auto& [name, c] : {std::pair{std::string("random_offset"), ev::TrussCase::kRandomOffset},
                                std::pair{std::string("recognition_error"), ev::TrussCase::kRecognitionError}}) {
    if (!args.cases.count(name)) continue;
    std::ofstream csv(args.out / ("trials_" + name + ".csv"));
    csv << "seed,verdict,outcome,chosen,lateral_error_m,confidence,target_visible\n";
    int pictures = 0;
    const auto r = ev::run_truss_case(
        c, *scanner, args.trials, args.seed, {},
        [&](const ev::TrussTrial& t, const ev::TrussScene& scene, const ev::SimulatedScan& s, const lc::TwoStageResult& o,
            const lc::PedicelDetection& d) {
          csv << fmt::format("{},{},{},{},{:.5f},{:.3f},{}\n", t.seed, ev::to_string(t.verdict), lc::to_string(t.outcome),
                             t.chosen_kind, t.lateral_error_m, t.confidence, t.target_visible ? 1 : 0);
          if (pictures >= args.pictures) return;
          ++pictures;
          std::vector<std::string> kind(s.scan.size());
          for (std::size_t i = 0; i < kind.size(); ++i) kind[i] = ev::object_kind(scene, s.truth_object[i]);
          const int chosen = d.cluster >= 0 ? o.clusters[static_cast<std::size_t>(d.cluster)].id : -1;
          write_scan(args.out / "scans" / fmt::format("{}_{}_{}.csv", name, t.seed, ev::to_string(t.verdict)), s, o.labels,
                     o.smoothed_range_m, kind, chosen);
        });
    std::cout << "## " << name << "\n\n| verdict | rate [95 % CI] |\n|---|---|\n"
              << "| aligned | " << rate(r.aligned) << " |\n| wrong | " << rate(r.wrong) << " |\n| out of view | "
              << rate(r.out_of_view) << " |\n| missed (in view, no move) | " << rate(r.missed) << " |\n\n";
    json << fmt::format(",\n  \"{}\": {{\"aligned\": {}, \"wrong\": {}, \"out_of_view\": {}, \"missed\": {}}}", name,
                        rate_json(r.aligned), rate_json(r.wrong), rate_json(r.out_of_view), rate_json(r.missed));
  }

  if (args.cases.count("stick")) {
    std::ofstream csv(args.out / "trials_stick.csv");
    csv << "seed,iou_reflectance,iou_distance_only\n";
    int pictures = 0;
    ev::StickEvalOptions so;
    const auto r = ev::run_stick_case(
        *scanner, args.trials, args.seed, so,
        [&](const ev::StickTrial& t, const ev::StickScene& scene, const ev::SimulatedScan& s,
            const lc::ReflectanceClusteringResult& with, const lc::ReflectanceClusteringResult& without) {
          csv << fmt::format("{},{:.4f},{:.4f}\n", t.seed, t.iou_reflectance, t.iou_distance_only);
          if (pictures >= args.pictures) return;
          ++pictures;
          std::vector<std::string> kind(s.scan.size(), "none");
          for (std::size_t i = 0; i < kind.size(); ++i) {
            if (s.truth_object[i] == scene.stick) kind[i] = s.truth_mixed[i] ? "stick_mixed" : "stick";
            if (s.truth_object[i] == scene.panel) kind[i] = s.truth_mixed[i] ? "panel_mixed" : "panel";
          }
          const int bw = with.brightest >= 0 ? with.clusters[static_cast<std::size_t>(with.brightest)].id : -1;
          write_scan(args.out / "scans" / fmt::format("stick_{}_reflectance.csv", t.seed), s, with.labels, {}, kind, bw);
          write_scan(args.out / "scans" / fmt::format("stick_{}_distance.csv", t.seed), s, without.labels, {}, kind, -1);
        });
    std::cout << "## stick (Figure 5.8 B, front " << so.scene.front_gap_m * 1e3
              << " mm before the panel)\n\n| method | correct segmentation [95 % CI] |\n|---|---|\n"
              << "| distance and reflectance | " << rate(r.reflectance_correct) << " |\n| distance alone | "
              << rate(r.distance_only_correct) << " |\n\n";
    json << fmt::format(",\n  \"stick\": {{\"front_gap_m\": {}, \"reflectance\": {}, \"distance_only\": {}}}",
                        so.scene.front_gap_m, rate_json(r.reflectance_correct), rate_json(r.distance_only_correct));
    // The same at other gaps: where distance alone starts to work.
    std::cout << "| front gap | with reflectance | distance alone |\n|---:|---|---|\n";
    json << ",\n  \"stick_by_gap\": [";
    bool first = true;
    for (const double gap : {0.002, 0.004, 0.008, 0.015, 0.03}) {
      ev::StickEvalOptions g;
      g.scene.front_gap_m = gap;
      const auto rg = ev::run_stick_case(*scanner, args.trials, args.seed + 100000, g);
      std::cout << fmt::format("| {:.0f} mm | {} | {} |\n", gap * 1e3, rate(rg.reflectance_correct), rate(rg.distance_only_correct));
      json << fmt::format("{}\n    {{\"front_gap_m\": {}, \"reflectance\": {}, \"distance_only\": {}}}", first ? "" : ",", gap,
                          rate_json(rg.reflectance_correct), rate_json(rg.distance_only_correct));
      first = false;
    }
    json << "\n  ]";
    std::cout << "\n";
  }

  if (args.cases.count("wrench")) {
    std::ofstream csv(args.out / "trials_wrench.csv");
    csv << "seed,outcome,true_pitch_deg,best_pitch_deg,error_deg,step_error_deg\n";
    std::ofstream sweeps(args.out / "wrench_sweeps.csv");
    sweeps << "seed,pitch_deg,reflectance,true_pitch_deg,best_pitch_deg\n";
    int pictures = 0;
    const auto r = ev::run_wrench_case(*scanner, args.trials, args.seed, {},
                                       [&](const ev::WrenchTrial& t, const std::vector<lc::AlignmentSample>& sweep) {
                                         csv << fmt::format("{},{},{:.4f},{:.4f},{:.4f},{:.4f}\n", t.seed,
                                                            lc::to_string(t.outcome), t.true_pitch_rad / kDeg,
                                                            t.best_pitch_rad / kDeg, t.error_rad / kDeg,
                                                            t.step_error_rad / kDeg);
                                         if (pictures++ >= args.pictures) return;
                                         for (const auto& s : sweep) {
                                           sweeps << fmt::format("{},{:.4f},{:.4f},{:.4f},{:.4f}\n", t.seed,
                                                                 s.pitch_rad / kDeg, s.reflectance, t.true_pitch_rad / kDeg,
                                                                 t.best_pitch_rad / kDeg);
                                         }
                                       });
    std::cout << "## wrench alignment (5.3.2)\n\n| figure | value |\n|---|---|\n"
              << fmt::format("| median pitch error | {:.2f} deg |\n| 90th percentile | {:.2f} deg |\n", r.median_error_deg,
                             r.p90_error_deg)
              << fmt::format("| median error of the brightest step alone (2 deg steps) | {:.2f} deg |\n",
                             r.median_step_error_deg)
              << "| within 1 deg | " << rate(r.within_1deg) << " |\n| peak found | " << rate(r.found) << " |\n\n";
    json << fmt::format(
        ",\n  \"wrench\": {{\"median_error_deg\": {:.4f}, \"p90_error_deg\": {:.4f}, \"median_step_error_deg\": {:.4f}, "
        "\"within_1deg\": {}, \"found\": {}}}",
        r.median_error_deg, r.p90_error_deg, r.median_step_error_deg, rate_json(r.within_1deg), rate_json(r.found));
  }
  json << "\n}\n";
  std::cout << "outputs in " << args.out.string() << "\n";
  return 0;
}
