// SPDX-License-Identifier: Apache-2.0
// sim_scan: one simulated measurement set of a scene's sensor, as JSON: per
// pixel the ray angle, the true range and what it hits, the raw read-outs,
// the read-out the driver would choose, and the distance the on-board
// (factory) calibration gives. For looking at a scene and for the plots of
// docs/simulator.md.
//
//   sim_scan SCENE.yaml [--sensor NAME] [--time S] [--index N] [--out FILE]
#include <cmath>
#include <optional>
#include <iostream>
#include <string>

#include <sim/fidelity.hpp>
#include <sim/firmware.hpp>
#include <sim/scene.hpp>
#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>

namespace cli = tinyline::cli;

using namespace tinyline::sim;

int main(int argc, char** argv) {
  std::string scene_path, sensor_name, out_path;
  double t = 3600.0;
  std::uint64_t index = 1;
  cli::App app{
      "One simulated measurement set of a scene's sensor, as JSON: per pixel the ray, the true range and "
      "what it hits, the raw read-outs, the read-out the driver would choose and the on-board calibration's "
      "distance (docs/simulator.md).",
      "sim_scan"};
  app.add_option("SCENE", scene_path, "scene YAML")->required();
  app.add_option("--sensor", sensor_name, "sensor name in the scene (default: the first)");
  app.add_option("--time", t, "sensor time of the set [s]")->check(cli::non_negative())->capture_default_str();
  app.add_option("--index", index, "set index (seeds its noise)")->check(cli::non_negative())->capture_default_str();
  app.add_option("--out", out_path, "JSON file to write (default: stdout)");
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return *rc;
  if (!out_path.empty() && !tinyline::files::output_allowed("sim_scan", out_path, {.inputs = {scene_path}})) return 1;
  try {
    const Scene s = load_scene(scene_path);
    const SensorMount* m = sensor_name.empty() ? (s.sensors.empty() ? nullptr : &s.sensors[0]) : s.sensor(sensor_name);
    if (!m) {
      std::cerr << "sim_scan: " << scene_path << ": no sensor"
                << (sensor_name.empty() ? "" : " named '" + sensor_name + "'") << "\n";
      return 1;
    }
    const TofLineSensor sensor(m->params);
    const SensorSet set = sensor.measure(s.world, m->T_world_sensor, t, m->params.acquisition.raw_pulses, index);
    const auto model = factory_calibration(m->params);
    const auto units = firmware_distances(set, model);  // 0.1 mm
    std::optional<tinyline::files::AtomicStream> file;
    if (!out_path.empty()) file.emplace(out_path);
    std::ostream& o = file ? static_cast<std::ostream&>(*file) : std::cout;
    o.precision(7);
    o << "{\"scene\": \"" << s.name << "\", \"sensor\": \"" << m->name << "\", \"temperature_c\": " << set.temperature_c
      << ", \"pulses\": [";
    for (std::size_t k = 0; k < set.readouts.size(); ++k) o << (k ? "," : "") << set.readouts[k].pulses;
    o << "],\n \"pixels\": [\n";
    for (int i = 0; i < sensor.pixels(); ++i) {
      const auto u = static_cast<std::size_t>(i);
      const PixelTruth& tr = set.truth[u];
      const int sel = select_readout(set, i);
      auto num = [](double v) { return std::isfinite(v) ? std::to_string(v) : std::string("null"); };
      o << "  {\"i\": " << i << ", \"angle\": " << sensor.pixel_angle_rad(i) << ", \"range\": " << num(tr.range_m)
        << ", \"object\": \"" << (tr.object >= 0 ? s.world.object(tr.object).name : "")
        << "\", \"lit\": " << (tr.lit ? "true" : "false") << ", \"mixed\": " << (tr.mixed ? "true" : "false")
        << ", \"a\": [";
      for (std::size_t k = 0; k < set.readouts.size(); ++k) o << (k ? "," : "") << set.readouts[k].a[u];
      o << "], \"b\": [";
      for (std::size_t k = 0; k < set.readouts.size(); ++k) o << (k ? "," : "") << set.readouts[k].b[u];
      o << "], \"selected\": " << sel << ", \"distance\": " << (units[u] > 0 ? num(units[u] / 1e4) : "null") << "}"
        << (i + 1 < sensor.pixels() ? ",\n" : "\n");
    }
    o << " ]}\n";
    if (file) file->commit();
    return o ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "sim_scan: " << e.what() << "\n";
    return 1;
  }
}
