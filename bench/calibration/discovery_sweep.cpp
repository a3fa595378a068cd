// SPDX-License-Identifier: Apache-2.0
// calibration_discovery_sweep: how often the residual loop names an effect on
// the simulator, over many seeds: the share of effect-free runs that name
// anything (the null rate; goal <= 5 %) and, per injected effect, the share
// that name it and how close the held-out error gets to the noise floor.
// The cases are those of the tests (tiny_laser_calibration/testing/
// sim_discovery_cases.cpp); the seeds must all be of one kind in the
// calibration's entry of the seed registry (tinyline/common/seeds.hpp): tuning
// seeds while choosing settings, held-out seeds for the figures in
// docs/calibration.md.
//
//   calibration_discovery_sweep --seeds 1000-1019 --case none
//   calibration_discovery_sweep --seeds 1000-1004 --case ambient_light --case group_leakage
//   calibration_discovery_sweep --seeds 1000-1004 --all --out sweep.csv
//   calibration_discovery_sweep --seeds 1-5 --case channel_offset --rounds   (why each run named what it named)
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>
#include <tinyline/common/seeds.hpp>

#include "sim_discovery_cases.hpp"

namespace seeds = tinyline::common::seeds;
namespace tt = tinyline::tiny_laser_calibration::testing;

namespace {

struct Args {
  seeds::SeedRange seeds{1, 5};
  std::vector<std::string> cases;
  std::string out;
  bool rounds = false;  ///< print each run's strongest candidates per round (why it named what it named)
};

// The use every seed of the range shares; nullopt when they differ or one is unregistered.
std::optional<seeds::SeedUse> range_use(const seeds::SeedRange& r) {
  const auto first = seeds::use_of(seeds::kCalibration, r.first);
  for (std::uint64_t s = r.first; s <= r.last; ++s) {
    if (seeds::use_of(seeds::kCalibration, s) != first) return std::nullopt;
  }
  return first;
}

int usage(const std::string& why) {
  std::cerr << "calibration_discovery_sweep: " << why
            << "\nusage: calibration_discovery_sweep --seeds FIRST-LAST (--case NAME ... | --all) [--out FILE.csv] "
               "[--rounds]\n"
            << "cases:";
  for (const auto& c : tt::discovery_cases()) std::cerr << " " << c.name;
  const auto& e = seeds::kCalibration;
  std::cerr << "\nseed ranges:";
  for (const auto& r : e.tuning) std::cerr << " tuning " << r.str();
  for (const auto& r : e.held_out) std::cerr << " held-out " << r.str();
  std::cerr << "\n";
  return 2;
}

bool parse_range(const std::string& s, seeds::SeedRange& r) {
  const auto dash = s.find('-');
  try {
    std::size_t used = 0;
    r.first = std::stoull(s.substr(0, dash), &used);
    r.last = dash == std::string::npos ? r.first : std::stoull(s.substr(dash + 1));
  } catch (const std::exception&) {
    return false;
  }
  return r.first <= r.last;
}

int parse(int argc, char** argv, Args& a) {
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    const bool has_value = i + 1 < argc;
    if (k == "--seeds" && has_value) {
      if (!parse_range(argv[++i], a.seeds)) return usage(std::string("--seeds: '") + argv[i] + "' is not FIRST-LAST");
    } else if (k == "--case" && has_value) {
      a.cases.push_back(argv[++i]);
    } else if (k == "--all") {
      for (const auto& c : tt::discovery_cases()) a.cases.push_back(c.name);
    } else if (k == "--rounds") {
      a.rounds = true;
    } else if (k == "--out" && has_value) {
      a.out = argv[++i];
    } else {
      return usage("unknown or incomplete option '" + k + "'");
    }
  }
  if (a.cases.empty()) return usage("no case chosen");
  for (const auto& n : a.cases) {
    bool known = false;
    for (const auto& c : tt::discovery_cases()) known = known || c.name == n;
    if (!known) return usage("unknown case '" + n + "'");
  }
  if (!range_use(a.seeds)) return usage("seeds mix tuning and held-out seeds (or are unregistered)");
  return 0;
}

// The four strongest candidates of each round and the bar of round 0.
void print_rounds(const tinyline::tiny_laser_calibration::DiscoveryResult& r) {
  for (std::size_t k = 0; k < r.rounds.size(); ++k) {
    std::fprintf(stderr, "  round %zu (z > %.2f):", k, r.z_threshold);
    for (std::size_t j = 0; j < std::min<std::size_t>(4, r.rounds[k].size()); ++j) {
      const auto& sc = r.rounds[k][j];
      std::fprintf(stderr, " %s/%s gain %.3f z %.1f;", sc.covariate.c_str(),
                   std::string(tinyline::tiny_laser_driver::to_string(sc.form)).c_str(), sc.gain, sc.z);
    }
    std::fprintf(stderr, "\n");
  }
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  if (const int rc = parse(argc, argv, a); rc != 0) return rc;
  if (tinyline::cli::only_check_options()) {  // the docs test checks the printed commands so
    tinyline::cli::print_options_ok("calibration_discovery_sweep");
    return 0;
  }
  const auto use = *range_use(a.seeds);
  std::optional<tinyline::files::AtomicStream> csv;  // checked before the sweep, renamed into place at its end
  if (!a.out.empty()) {
    try {
      csv.emplace(a.out, tinyline::files::named("sweep table"));
    } catch (const tinyline::files::FileError& e) {
      return usage(e.what());
    }
    *csv << "case,seed,named,first_effect,before_m,after_m,floor_m,twin_effects\n";
  }
  std::printf("seeds %llu-%llu (%s)\n", static_cast<unsigned long long>(a.seeds.first),
              static_cast<unsigned long long>(a.seeds.last), std::string(seeds::to_string(use)).c_str());
  std::printf(
      "| case | runs | named as expected | named anything | after / floor (median, max) | twin named anything |\n");
  std::printf("|---|---|---|---|---|---|\n");
  for (const auto& name : a.cases) {
    const auto& c = tt::discovery_case(name);
    int runs = 0, hits = 0, any = 0, twin_any = 0;
    std::vector<double> ratio;
    for (std::uint64_t seed = a.seeds.first; seed <= a.seeds.last; ++seed) {
      const auto o = tt::run_case(c, seed);
      ++runs;
      hits += o.named ? 1 : 0;
      any += o.result.effects.empty() ? 0 : 1;
      twin_any += o.twin.effects.empty() ? 0 : 1;
      ratio.push_back(o.result.rmse_after_m / o.floor_m);
      if (csv) {
        *csv << c.name << ',' << seed << ',' << (o.named ? 1 : 0) << ',' << o.names() << ',' << o.result.rmse_before_m
             << ',' << o.result.rmse_after_m << ',' << o.floor_m << ',' << o.twin.effects.size() << '\n';
      }
      std::fprintf(stderr, "%s seed %llu: %s, %.2f -> %.2f cm (floor %.2f cm); twin: %s\n", c.name.c_str(),
                   static_cast<unsigned long long>(seed), o.names().c_str(), 100 * o.result.rmse_before_m,
                   100 * o.result.rmse_after_m, 100 * o.floor_m, tt::effect_names(o.twin).c_str());
      if (a.rounds) print_rounds(o.result);
    }
    std::sort(ratio.begin(), ratio.end());
    std::printf("| %s | %d | %d (%.0f %%) | %d | %.2f, %.2f | %d |\n", c.name.c_str(), runs, hits, 100.0 * hits / runs,
                any, ratio[ratio.size() / 2], ratio.back(), twin_any);
    std::fflush(stdout);
  }
  if (csv) {
    try {
      csv->commit();
    } catch (const tinyline::files::FileError& e) {
      std::fprintf(stderr, "calibration_discovery_sweep: %s\n", e.what());
      return 1;
    }
  }
  return 0;
}
