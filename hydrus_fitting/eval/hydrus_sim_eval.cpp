// The Hydrus grasp in the physics simulator under the three emission
// schedules, written as CSV for docs/hydrus_fitting.md:
//
//   hydrus_sim_eval [--schedules all_on,time_slicing,colouring] [--start S] [--end S]
//                   [--scene YAML] [--robot YAML] [--calibration YAML]
//                   [--updates FILE] [--rates FILE] [--no-base-motion]
//
// The estimator gets the base's pose, as circle_fitter does in the launch
// file, so that each scan is moved by the base's own motion to the update's
// newest scan; --no-base-motion leaves the scans where the joints put them.
//
// Paths default to the source tree's hydrus4_grasp scene, hydrus4 robot and
// the simulated 3.6 mm sensor's calibration.
//
// scripts/plots/hydrus_grasp.py plots the centre error over time.
#include <chrono>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "sim_study.hpp"
#include "write_output.hpp"

namespace ev = tinyline::hydrus_fitting::eval;

namespace {

int usage() {
  std::cerr << "usage: hydrus_sim_eval [--schedules all_on,time_slicing,colouring] [--start S] [--end S] [--scene YAML] "
               "[--robot YAML] [--calibration YAML] [--updates FILE] [--rates FILE] [--no-base-motion]\n";
  return 2;
}

bool write(const std::string& path, const std::string& text) { return ev::write_output("hydrus_sim_eval", path, text); }

}  // namespace

int main(int argc, char** argv) {
  const std::string src = TINYLINE_SOURCE_DIR;
  std::string schedules = "all_on,time_slicing,colouring", updates_path, rates_path;
  std::string scene = src + "/sim/config/scenes/hydrus4_grasp.yaml";
  std::string robot = src + "/hydrus_fitting/config/hydrus4.yaml";
  std::string calibration = src + "/tiny_laser_driver/config/calibration/sim_tiny_tof_3p6mm.yaml";
  double start_s = 0.0, end_s = -1.0;
  bool base_motion = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--no-base-motion") {
      base_motion = false;
      continue;
    }
    if (i + 1 >= argc) return usage();
    if (a == "--schedules") {
      schedules = argv[++i];
    } else if (a == "--end") {
      try {
        end_s = std::stod(argv[++i]);
      } catch (const std::exception&) {
        return usage();
      }
    } else if (a == "--start") {
      try {
        start_s = std::stod(argv[++i]);
      } catch (const std::exception&) {
        return usage();
      }
    } else if (a == "--scene") {
      scene = argv[++i];
    } else if (a == "--robot") {
      robot = argv[++i];
    } else if (a == "--calibration") {
      calibration = argv[++i];
    } else if (a == "--updates") {
      updates_path = argv[++i];
    } else if (a == "--rates") {
      rates_path = argv[++i];
    } else {
      return usage();
    }
  }
  std::vector<ev::SimStudyResult> runs;
  std::stringstream list(schedules);
  std::string name;
  try {
    while (std::getline(list, name, ',')) {
      ev::SimStudyParams p;
      p.scene_path = scene;
      p.robot_description = robot;
      p.calibration_path = calibration;
      p.schedule = name;
      p.start_s = start_s;
      p.end_s = end_s;
      p.base_motion = base_motion;
      const auto t0 = std::chrono::steady_clock::now();
      runs.push_back(ev::sim_study(p));
      const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::cerr << name << ": " << runs.back().updates.size() << " updates, " << runs.back().simulated_s
                << " s simulated in " << wall << " s\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "hydrus_sim_eval: " << e.what() << "\n";
    return 1;
  }
  bool ok = write(updates_path, ev::sim_updates_csv(runs));
  ok = write(rates_path, ev::sim_rates_csv(runs)) && ok;
  return ok ? 0 : 1;
}
