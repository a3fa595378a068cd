// SPDX-License-Identifier: Apache-2.0
// Simulated sensor sets per second on one core, against references in the
// same run:
//   BM_RaycastReference   the bare ray casts one set needs (sub-rays, truth
//                         rays, shadow rays), no physics: the floor.
//   BM_Set/<scene>        a full raw-mode set (5 read-outs, noise, truth).
//   BM_SetCrosstalk       one set of one of 4 sensors around a cylinder while
//                         the 3 others emit in step (worst case: every pulse
//                         overlaps), the Hydrus configuration.
//   BM_EncodeRawSet       the 5 wire frames of a set (virtual device cost).
// The real sensor makes at most 100 sets/s (distance mode, short range) and
// about 35 raw sets/s; the goal is >= 20x that per core.
#include <benchmark/benchmark.h>

#include <cmath>

#include <tiny_laser_driver/protocol.hpp>

#include <sim/firmware.hpp>
#include <sim/scene.hpp>
#include <sim/tof_sensor.hpp>

using namespace tinyline::sim;

namespace {

std::string scene(const char* name) { return std::string(TINYLINE_SOURCE_DIR) + "/sim/config/scenes/" + name; }

const char* kScenes[] = {"calibration_rail.yaml", "wrench_panel.yaml", "stick_near_background.yaml"};

void BM_Set(benchmark::State& state) {
  const Scene s = load_scene(scene(kScenes[state.range(0)]));
  const TofLineSensor sensor(s.sensors[0].params);
  const auto& sched = sensor.params().acquisition.raw_pulses;
  std::uint64_t i = 0;
  for (auto _ : state) {
    SensorSet set = sensor.measure(s.world, s.sensors[0].T_world_sensor, 3600.0, sched, i++);
    benchmark::DoNotOptimize(set.readouts.back().a.data());
  }
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(kScenes[state.range(0)]);
}
BENCHMARK(BM_Set)->DenseRange(0, 2)->Unit(benchmark::kMicrosecond);

// The same rays without the physics: sub-rays, one shadow ray per hit, one truth ray per pixel.
void BM_RaycastReference(benchmark::State& state) {
  const Scene s = load_scene(scene(kScenes[state.range(0)]));
  const SensorParams& p = s.sensors[0].params;
  const TofLineSensor sensor(p);
  const Eigen::Isometry3d T = s.sensors[0].T_world_sensor;
  const Eigen::Vector3d E = T * Eigen::Vector3d(p.emitter.baseline_m, 0, 0);
  const int n = p.lens.pixels, sub = p.lens.subrays_per_pixel;
  std::vector<Eigen::Vector3d> dirs;
  const double pitch = p.lens.pitch_mm();
  for (int j = 0; j < n * sub; ++j)
    dirs.push_back(T.linear() * Eigen::Vector3d(((j + 0.5) / sub - 0.5 * n) * pitch, 0, p.lens.focal_mm).normalized());
  for (int i = 0; i < n; ++i) dirs.push_back(T.linear() * sensor.pixel_direction(i));
  for (auto _ : state) {
    int hits = 0;
    for (const auto& d : dirs) {
      const auto h = s.world.raycast(Ray{T.translation(), d}, 1e-6, 30.0);
      if (h) hits += s.world.occluded(h->point + 1e-7 * h->normal, E) ? 0 : 1;
    }
    benchmark::DoNotOptimize(hits);
  }
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(kScenes[state.range(0)]);
}
BENCHMARK(BM_RaycastReference)->DenseRange(0, 2)->Unit(benchmark::kMicrosecond);

// Four sensors in one plane around a cylinder (r = 8 cm), 30 cm from its axis.
void BM_SetCrosstalk(benchmark::State& state) {
  World w;
  w.add({"cylinder", CylinderShape{0.08, 0.5}, Eigen::Isometry3d(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX())),
         *w.materials().find("white_matte")});
  SensorParams p;
  std::vector<Eigen::Isometry3d> poses;
  for (int k = 0; k < 4; ++k) {
    const double a = k * M_PI / 2 + 0.2;  // not exactly facing each other
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0.3 * std::sin(a), 0, -0.3 * std::cos(a));
    T.linear() = Eigen::AngleAxisd(-a, Eigen::Vector3d::UnitY()).toRotationMatrix();
    poses.push_back(T);
  }
  const TofLineSensor sensor(p);
  std::vector<ForeignEmitter> others;
  for (int k = 1; k < 4; ++k) {
    ForeignEmitter f;
    f.T_world_sensor = poses[static_cast<std::size_t>(k)];
    f.emitter = p.emitter;
    f.first_pulse_s = 10.0;  // in step with ours: every pulse overlaps
    f.pulse_rate_hz = p.emitter.pulse_rate_hz;
    f.on_intervals = {{0.0, 1e9}};
    others.push_back(f);
  }
  std::uint64_t i = 0;
  int xt = 0;
  for (auto _ : state) {
    SensorSet set = sensor.measure(w, poses[0], 10.0, p.acquisition.raw_pulses, i++, others);
    xt = set.crosstalk_pulses;
    benchmark::DoNotOptimize(set.readouts.back().a.data());
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["crosstalk_pulses"] = xt;
}
BENCHMARK(BM_SetCrosstalk)->Unit(benchmark::kMicrosecond);

void BM_EncodeRawSet(benchmark::State& state) {
  const Scene s = load_scene(scene("calibration_rail.yaml"));
  const TofLineSensor sensor(s.sensors[0].params);
  const SensorSet set =
      sensor.measure(s.world, s.sensors[0].T_world_sensor, 3600.0, sensor.params().acquisition.raw_pulses, 1);
  std::vector<std::uint8_t> bytes;
  for (auto _ : state) {
    bytes.clear();
    for (const auto& f : raw_frames(set)) tinyline::tiny_laser_driver::encode_raw_frame(f, bytes);
    benchmark::DoNotOptimize(bytes.data());
  }
  state.SetItemsProcessed(state.iterations());
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * bytes.size()));
}
BENCHMARK(BM_EncodeRawSet)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
