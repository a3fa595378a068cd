// calibration_sim_rail_bag: records a calibration session on the simulated
// rail as a bag (virtual sensor + recorder on sim time), the input of
// `tinyline calib collect` in docs/calibration.md. Not installed.
//
//   calibration_sim_rail_bag --scene sim/config/scenes/calibration_rail.yaml -o rail.mcap
//       [--from 0.15] [--to 2.0] [--step 0.05] [--visits 2] [--sets 3] [--power-on-age 0] [--seed 7]
#include <algorithm>
#include <iostream>
#include <random>
#include <string>

#include "sim_rail_session.hpp"

int main(int argc, char** argv) {
  namespace tt = tinyline::tiny_laser_calibration::testing;
  tt::SimRailSession s;
  double from = 0.15, to = 2.0, step = 0.05;
  int visits = 2;
  unsigned seed = 7;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto next = [&]() -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
        return argv[++i];
      };
      if (a == "--scene") s.scene = next();
      else if (a == "-o") s.bag_path = next();
      else if (a == "--from") from = std::stod(next());
      else if (a == "--to") to = std::stod(next());
      else if (a == "--step") step = std::stod(next());
      else if (a == "--visits") visits = std::stoi(next());
      else if (a == "--sets") s.sets_per_distance = std::stoi(next());
      else if (a == "--power-on-age") s.power_on_age_s = std::stod(next());
      else if (a == "--seed") seed = static_cast<unsigned>(std::stoul(next()));
      else throw std::invalid_argument("unknown option " + a);
    }
    if (s.scene.empty() || s.bag_path.empty() || !(step > 0) || !(from > 0) || !(to >= from) || visits < 1) {
      throw std::invalid_argument("needs --scene SCENE.yaml -o OUT.mcap and a valid --from/--to/--step/--visits");
    }
  } catch (const std::exception& e) {
    std::cerr << "calibration_sim_rail_bag: " << e.what() << "\n";
    return 2;
  }
  for (int v = 0; v < visits; ++v) {
    for (double d = from; d <= to + 1e-9; d += step) s.distances_m.push_back(d);
  }
  std::mt19937 rng(seed);
  std::shuffle(s.distances_m.begin(), s.distances_m.end(), rng);
  const auto r = tt::record_sim_rail_session(s);
  if (!r.error.empty()) {
    std::cerr << "calibration_sim_rail_bag: " << r.error << "\n";
    return 1;
  }
  std::cout << "wrote " << s.bag_path << ": " << r.raw_scans << " raw scans, " << r.truths << " truths ("
            << s.distances_m.size() << " rail positions x " << s.sets_per_distance << " sets), " << r.dropped
            << " dropped\n";
  return r.dropped == 0 ? 0 : 1;
}
