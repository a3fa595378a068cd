// The Monte-Carlo studies of docs/hydrus_fitting.md, written as CSV.
//
//   hydrus_eval kcr        [--trials N] [--out FILE]
//   hydrus_eval robustness [--trials N] [--out FILE]
//   hydrus_eval ray_noise  [--trials N] [--out FILE]
//   hydrus_eval second_order [--trials N] [--out FILE]   (N noise draws)
//
// kcr and second_order also take --seed N, --arcs DEG,DEG,... and
// --sigmas M,M,... (noise SDs [m]) to run a part of the grid or other draws,
// and --points N (points per arc).
//
// scripts/plots/hydrus_kcr.py (figure and table) and hydrus_tables.py read the CSVs and
// write the tables and figures of the document.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <tinyline/common/cli.hpp>

#include "montecarlo.hpp"
#include "write_output.hpp"

namespace ev = tinyline::hydrus_fitting::eval;

namespace {

bool write(const std::string& path, const std::string& text) { return ev::write_output("hydrus_eval", path, text); }

/// What the command line asks for (unset fields keep the study's defaults).
struct Request {
  int trials = 0;
  std::optional<std::uint64_t> seed;
  int points = 0;
  std::vector<double> arcs_deg, sigmas_m;
  std::string out;
};

/// --trials and --out for every study; the grid options for kcr and second_order.
void add_options(CLI::App& study, Request& r, bool grid) {
  study.add_option("--trials", r.trials, "trials (second_order: noise draws)")->check(CLI::Range(1, 1 << 30));
  study.add_option("--out", r.out, "CSV file to write (default: stdout)");
  if (!grid) return;
  study.add_option("--seed", r.seed, "seed of the noise draws")->check(tinyline::common::kNonNegative);
  study.add_option("--points", r.points, "points per arc")->check(CLI::Range(3, 1 << 20));
  study.add_option("--arcs", r.arcs_deg, "arcs [deg], comma-separated")
      ->delimiter(',')
      ->check(tinyline::common::kPositive);
  study.add_option("--sigmas", r.sigmas_m, "noise SDs [m], comma-separated")
      ->delimiter(',')
      ->check(tinyline::common::kPositive);
}

template <class Params>
void apply_grid(const Request& r, Params& p) {
  if (r.seed) p.seed = *r.seed;
  if (!r.arcs_deg.empty()) p.arcs_deg = r.arcs_deg;
  if (!r.sigmas_m.empty()) p.sigmas_m = r.sigmas_m;
  if (r.points > 0) p.points = r.points;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"The Monte-Carlo studies of docs/hydrus_fitting.md, written as CSV.", "hydrus_eval"};
  app.require_subcommand(1);
  Request r;
  CLI::App* kcr = app.add_subcommand("kcr", "circle fits against the KCR bound over arcs and noise");
  CLI::App* robustness = app.add_subcommand("robustness", "robust fitting on the robot's fused scans with clutter");
  CLI::App* ray_noise = app.add_subcommand("ray_noise", "noise along the rays versus isotropic noise");
  CLI::App* second_order = app.add_subcommand("second_order", "the second-order correction over arcs and noise");
  add_options(*kcr, r, true);
  add_options(*robustness, r, false);
  add_options(*ray_noise, r, false);
  add_options(*second_order, r, true);
  if (const auto rc = tinyline::common::parse_command_line(app, argc, argv)) return *rc;

  const std::string description = std::string(TINYLINE_SOURCE_DIR) + "/hydrus_fitting/config/hydrus4.yaml";
  if (kcr->parsed()) {
    ev::KcrStudyParams p;
    if (r.trials > 0) p.trials = r.trials;
    apply_grid(r, p);
    return write(r.out, ev::kcr_csv(ev::kcr_study(p))) ? 0 : 1;
  }
  if (robustness->parsed()) {
    ev::RobustnessParams p;
    p.robot_description = description;
    if (r.trials > 0) p.trials = r.trials;
    return write(r.out, ev::robustness_csv(ev::robustness_study(p))) ? 0 : 1;
  }
  if (ray_noise->parsed()) {
    ev::RayNoiseParams p;
    p.robot_description = description;
    if (r.trials > 0) p.trials = r.trials;
    return write(r.out, ev::ray_noise_csv(ev::ray_noise_study(p))) ? 0 : 1;
  }
  ev::SecondOrderParams p;
  if (r.trials > 0) p.draws = r.trials;
  apply_grid(r, p);
  return write(r.out, ev::second_order_csv(ev::second_order_study(p))) ? 0 : 1;
}
