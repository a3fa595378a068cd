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
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "montecarlo.hpp"
#include "write_output.hpp"

namespace ev = tinyline::hydrus_fitting::eval;

namespace {

int usage() {
  std::cerr << "usage: hydrus_eval kcr|robustness|ray_noise|second_order [--trials N] [--out FILE]\n"
               "         kcr, second_order: [--seed N] [--arcs DEG,...] [--sigmas M,...] [--points N]\n";
  return 2;
}

bool write(const std::string& path, const std::string& text) { return ev::write_output("hydrus_eval", path, text); }

/// "a,b,c" as numbers > 0; empty on a malformed list.
std::vector<double> parse_list(const std::string& s) {
  std::vector<double> v;
  std::size_t pos = 0;
  while (pos <= s.size()) {
    const std::size_t end = std::min(s.find(',', pos), s.size());
    const std::string item = s.substr(pos, end - pos);
    char* stop = nullptr;
    const double x = std::strtod(item.c_str(), &stop);
    if (item.empty() || *stop != '\0' || !(x > 0.0)) return {};
    v.push_back(x);
    pos = end + 1;
  }
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage();
  const std::string cmd = argv[1];
  int trials = -1;
  long long seed = -1;
  int points = -1;
  std::vector<double> arcs, sigmas;
  std::string out;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--trials" && i + 1 < argc) {
      trials = std::atoi(argv[++i]);
      if (trials <= 0) return usage();
    } else if (a == "--seed" && i + 1 < argc) {
      seed = std::atoll(argv[++i]);
      if (seed < 0) return usage();
    } else if (a == "--points" && i + 1 < argc) {
      points = std::atoi(argv[++i]);
      if (points < 3) return usage();
    } else if (a == "--arcs" && i + 1 < argc) {
      arcs = parse_list(argv[++i]);
      if (arcs.empty()) return usage();
    } else if (a == "--sigmas" && i + 1 < argc) {
      sigmas = parse_list(argv[++i]);
      if (sigmas.empty()) return usage();
    } else if (a == "--out" && i + 1 < argc) {
      out = argv[++i];
    } else {
      return usage();
    }
  }
  if ((seed >= 0 || points > 0 || !arcs.empty() || !sigmas.empty()) && cmd != "kcr" && cmd != "second_order") {
    std::cerr << "hydrus_eval " << cmd << ": --seed, --points, --arcs and --sigmas are for kcr and second_order only\n";
    return 2;
  }
  if (cmd == "kcr") {
    ev::KcrStudyParams p;
    if (trials > 0) p.trials = trials;
    if (seed >= 0) p.seed = static_cast<std::uint64_t>(seed);
    if (!arcs.empty()) p.arcs_deg = arcs;
    if (!sigmas.empty()) p.sigmas_m = sigmas;
    if (points > 0) p.points = points;
    return write(out, ev::kcr_csv(ev::kcr_study(p))) ? 0 : 1;
  }
  if (cmd == "robustness") {
    ev::RobustnessParams p;
    p.robot_description = std::string(TINYLINE_SOURCE_DIR) + "/hydrus_fitting/config/hydrus4.yaml";
    if (trials > 0) p.trials = trials;
    return write(out, ev::robustness_csv(ev::robustness_study(p))) ? 0 : 1;
  }
  if (cmd == "ray_noise") {
    ev::RayNoiseParams p;
    p.robot_description = std::string(TINYLINE_SOURCE_DIR) + "/hydrus_fitting/config/hydrus4.yaml";
    if (trials > 0) p.trials = trials;
    return write(out, ev::ray_noise_csv(ev::ray_noise_study(p))) ? 0 : 1;
  }
  if (cmd == "second_order") {
    ev::SecondOrderParams p;
    if (trials > 0) p.draws = trials;
    if (seed >= 0) p.seed = static_cast<std::uint64_t>(seed);
    if (!arcs.empty()) p.arcs_deg = arcs;
    if (!sigmas.empty()) p.sigmas_m = sigmas;
    if (points > 0) p.points = points;
    return write(out, ev::second_order_csv(ev::second_order_study(p))) ? 0 : 1;
  }
  return usage();
}
