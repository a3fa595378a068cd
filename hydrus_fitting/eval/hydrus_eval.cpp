// SPDX-License-Identifier: Apache-2.0
// The Monte-Carlo studies of docs/hydrus_fitting.md, written as CSV.
//
//   hydrus_eval kcr        [--trials N] [--seed N] [--tuning] [--out FILE]
//   hydrus_eval robustness [--trials N] [--seed N] [--tuning] [--out FILE]
//   hydrus_eval ray_noise  [--trials N] [--seed N] [--tuning] [--out FILE]
//   hydrus_eval second_order [--trials N] [--seed N] [--tuning] [--out FILE]   (N noise draws)
//   hydrus_eval correction [--trials N] [--seed N] [--tuning] [--out FILE]
//                          [--arcs ...] [--point-counts 30,100,400] [--sigma-over-r ...]
//                          [--outliers 0,0.1] [--noise isotropic,rays]
//
// Every study takes --seed N (other noise draws) and --tuning (the run is
// for choosing parameters: a seed that is not a tuning seed of
// common/seeds.hpp is refused); the seeds and what they are go to stderr.
// kcr and second_order also take --arcs DEG,DEG,... and --sigmas M,M,...
// (noise SDs [m]) to run a part of the grid, and --points N (points per arc).
//
// scripts/plots/hydrus_kcr.py (figure and table) and hydrus_tables.py read the CSVs and
// write the tables and figures of the document.
#include <cstdint>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <tinyline/common/cli.hpp>
#include <tinyline/common/seeds.hpp>

#include "correction_study.hpp"
#include "montecarlo.hpp"
#include "write_output.hpp"

namespace cli = tinyline::cli;

namespace ev = tinyline::hydrus_fitting::eval;

namespace {

/// What the command line asks for (unset fields keep the study's defaults).
struct Request {
  int trials = 0;
  std::optional<std::uint64_t> seed;
  bool tuning = false;
  int points = 0;
  std::vector<double> arcs_deg, sigmas_m;
  std::string out;
  // correction only
  std::vector<int> point_counts;
  std::vector<double> sigma_over_r, outliers;
  std::vector<std::string> noise;
};

/// --trials and --out for every study; the grid options for kcr and second_order.
void add_options(cli::App& study, Request& r, bool grid) {
  study.add_option("--trials", r.trials, "trials (second_order: noise draws)")->check(cli::range(1, 1 << 30));
  study.add_option("--out", r.out, "CSV file to write (default: stdout)");
  study.add_option("--seed", r.seed, "seed of the noise draws")->check(cli::non_negative());
  study.add_flag("--tuning", r.tuning, "this run is for choosing parameters: refuse a seed that is not a tuning seed");
  if (!grid) return;
  study.add_option("--points", r.points, "points per arc")->check(cli::range(3, 1 << 20));
  study.add_option("--arcs", r.arcs_deg, "arcs [deg], comma-separated")->delimiter(',')->check(cli::positive());
  study.add_option("--sigmas", r.sigmas_m, "noise SDs [m], comma-separated")->delimiter(',')->check(cli::positive());
}

/// The study's seed from the request; false (said on stderr) when a tuning
/// run asks for a seed that is not a tuning seed. The seed's label goes to
/// stderr, the CSV's figures come from it.
template <class Params>
bool apply_seed(const std::string& study, const Request& r, Params& p) {
  namespace seeds = tinyline::common::seeds;
  if (r.seed) p.seed = *r.seed;
  const std::vector<std::uint64_t> used{p.seed};
  try {
    if (r.tuning) seeds::require_tuning(seeds::kHydrus, used);
  } catch (const std::invalid_argument& e) {
    std::cerr << "hydrus_eval " << study << ": " << e.what() << "\n";
    return false;
  }
  std::cerr << "hydrus_eval " << study << ": " << seeds::describe(seeds::kHydrus, used) << "\n";
  return true;
}

template <class Params>
void apply_grid(const Request& r, Params& p) {
  if (!r.arcs_deg.empty()) p.arcs_deg = r.arcs_deg;
  if (!r.sigmas_m.empty()) p.sigmas_m = r.sigmas_m;
  if (r.points > 0) p.points = r.points;
}

/// The correction study's own grid options.
void add_correction_options(cli::App& study, Request& r) {
  add_options(study, r, false);
  study.add_option("--arcs", r.arcs_deg, "arcs [deg], comma-separated")->delimiter(',')->check(cli::positive());
  study.add_option("--point-counts", r.point_counts, "points per arc, comma-separated")
      ->delimiter(',')
      ->check(cli::range(4, 1 << 20));
  study.add_option("--sigma-over-r", r.sigma_over_r, "noise SD over the radius, comma-separated")
      ->delimiter(',')
      ->check(cli::positive());
  study.add_option("--outliers", r.outliers, "shares of outliers, comma-separated")
      ->delimiter(',')
      ->check(cli::range(0.0, 0.5));
  study.add_option("--noise", r.noise, "isotropic and/or rays, comma-separated")
      ->delimiter(',')
      ->check(cli::one_of({"isotropic", "rays"}));
}

}  // namespace

int main(int argc, char** argv) {
  cli::App app{"The Monte-Carlo studies of docs/hydrus_fitting.md, written as CSV.", "hydrus_eval"};
  app.require_subcommand(1);
  Request r;
  cli::App* kcr = app.add_subcommand("kcr", "circle fits against the KCR bound over arcs and noise");
  cli::App* robustness = app.add_subcommand("robustness", "robust fitting on the robot's fused scans with clutter");
  cli::App* ray_noise = app.add_subcommand("ray_noise", "noise along the rays versus isotropic noise");
  cli::App* second_order = app.add_subcommand("second_order", "the second-order correction over arcs and noise");
  cli::App* correction = app.add_subcommand(
      "correction", "the second-order correction outside its design: points, sigma/r, outliers, ray noise");
  add_options(*kcr, r, true);
  add_options(*robustness, r, false);
  add_options(*ray_noise, r, false);
  add_options(*second_order, r, true);
  add_correction_options(*correction, r);
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return *rc;

  const std::string description = std::string(TINYLINE_SOURCE_DIR) + "/hydrus_fitting/config/hydrus4.yaml";
  auto out = ev::Output::open("hydrus_eval", r.out, {description});
  if (!out) return 1;
  if (kcr->parsed()) {
    ev::KcrStudyParams p;
    if (r.trials > 0) p.trials = r.trials;
    apply_grid(r, p);
    if (!apply_seed("kcr", r, p)) return 2;
    return out->write(ev::kcr_csv(ev::kcr_study(p))) ? 0 : 1;
  }
  if (robustness->parsed()) {
    ev::RobustnessParams p;
    p.robot_description = description;
    if (r.trials > 0) p.trials = r.trials;
    if (!apply_seed("robustness", r, p)) return 2;
    return out->write(ev::robustness_csv(ev::robustness_study(p))) ? 0 : 1;
  }
  if (ray_noise->parsed()) {
    ev::RayNoiseParams p;
    p.robot_description = description;
    if (r.trials > 0) p.trials = r.trials;
    if (!apply_seed("ray_noise", r, p)) return 2;
    return out->write(ev::ray_noise_csv(ev::ray_noise_study(p))) ? 0 : 1;
  }
  if (correction->parsed()) {
    ev::CorrectionStudyParams p;
    if (r.trials > 0) p.trials = r.trials;
    if (!r.arcs_deg.empty()) p.arcs_deg = r.arcs_deg;
    if (!r.point_counts.empty()) p.points = r.point_counts;
    if (!r.sigma_over_r.empty()) p.sigma_over_r = r.sigma_over_r;
    if (!r.outliers.empty()) p.outlier_fractions = r.outliers;
    if (!r.noise.empty()) {
      p.noise.clear();
      for (const auto& n : r.noise) p.noise.push_back(n == "rays" ? ev::NoiseKind::kRays : ev::NoiseKind::kIsotropic);
    }
    if (!apply_seed("correction", r, p)) return 2;
    return out->write(ev::correction_csv(ev::correction_study(p))) ? 0 : 1;
  }
  ev::SecondOrderParams p;
  if (r.trials > 0) p.draws = r.trials;
  apply_grid(r, p);
  if (!apply_seed("second_order", r, p)) return 2;
  return out->write(ev::second_order_csv(ev::second_order_study(p))) ? 0 : 1;
}
