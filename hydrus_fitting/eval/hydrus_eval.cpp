// The Monte-Carlo studies of docs/hydrus_fitting.md, written as CSV.
//
//   hydrus_eval kcr        [--trials N] [--out FILE]
//   hydrus_eval robustness [--trials N] [--out FILE]
//   hydrus_eval ray_noise  [--trials N] [--out FILE]
//   hydrus_eval second_order [--trials N] [--out FILE]   (N noise draws)
//
// scripts/plots/hydrus_kcr.py (figure and table) and hydrus_tables.py read the CSVs and
// write the tables and figures of the document.
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>

#include "montecarlo.hpp"
#include "write_output.hpp"

namespace ev = tinyline::hydrus_fitting::eval;

namespace {

int usage() {
  std::cerr << "usage: hydrus_eval kcr|robustness|ray_noise|second_order [--trials N] [--out FILE]\n";
  return 2;
}

bool write(const std::string& path, const std::string& text) { return ev::write_output("hydrus_eval", path, text); }

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage();
  const std::string cmd = argv[1];
  int trials = -1;
  std::string out;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--trials" && i + 1 < argc) {
      trials = std::atoi(argv[++i]);
      if (trials <= 0) return usage();
    } else if (a == "--out" && i + 1 < argc) {
      out = argv[++i];
    } else {
      return usage();
    }
  }
  if (cmd == "kcr") {
    ev::KcrStudyParams p;
    if (trials > 0) p.trials = trials;
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
    return write(out, ev::second_order_csv(ev::second_order_study(p))) ? 0 : 1;
  }
  return usage();
}
