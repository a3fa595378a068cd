// SPDX-License-Identifier: Apache-2.0
#include <sim/system.hpp>

#include <cmath>
#include <filesystem>
#include <map>
#include <stdexcept>

#include <tinyline/common/random.hpp>

namespace tinyline::sim {

SimulatedSystem::SimulatedSystem(Scene scene, SystemOptions options)
    : scene_(std::move(scene)),
      options_(options),
      t0_(std::chrono::steady_clock::now()),
      wall0_(std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count()) {
  for (std::size_t i = 0; i < scene_.sensors.size(); ++i) {
    const SensorMount& m = scene_.sensors[i];
    common::XoshiroRandom rng(common::mix_seed(m.params.seed, 0xC10Cull, i));
    const double ppm = options_.clock_ppm_sd * rng.normal();
    sensors_.push_back(
        SensorState{m, TofLineSensor(m.params), m.params.emitter.pulse_rate_hz * (1.0 + 1e-6 * ppm), {}, 0.0});
  }
}

std::shared_ptr<SimulatedSystem> SimulatedSystem::from_file(const std::string& scene_path, SystemOptions options) {
  return std::make_shared<SimulatedSystem>(load_scene(scene_path), options);
}

std::shared_ptr<SimulatedSystem> SimulatedSystem::shared(const std::string& scene_path, SystemOptions options) {
  static std::mutex mu;
  static std::map<std::string, std::weak_ptr<SimulatedSystem>> systems;
  std::error_code ec;
  std::string key = std::filesystem::weakly_canonical(scene_path, ec).string();
  if (ec) key = scene_path;
  std::lock_guard lock(mu);
  if (auto it = systems.find(key); it != systems.end()) {
    if (auto s = it->second.lock()) return s;
  }
  auto s = from_file(scene_path, options);
  systems[key] = s;
  return s;
}

double SimulatedSystem::bus_epoch(double bus_time_s) {
  std::lock_guard lock(epoch_mu_);
  if (!bus_epoch_) bus_epoch_ = bus_time_s;
  return *bus_epoch_;
}

int SimulatedSystem::add_observer(std::function<void(std::size_t, const SensorSet&)> fn) {
  std::lock_guard lock(observers_mu_);
  observers_.emplace_back(next_observer_, std::move(fn));
  return next_observer_++;
}

void SimulatedSystem::remove_observer(int id) {
  std::lock_guard lock(observers_mu_);
  std::erase_if(observers_, [id](const auto& o) { return o.first == id; });
}

void SimulatedSystem::notify(std::size_t sensor, const SensorSet& set) {
  std::lock_guard lock(observers_mu_);
  for (const auto& [id, fn] : observers_) fn(sensor, set);
}

double SimulatedSystem::now() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
}

std::size_t SimulatedSystem::sensor_index(const std::string& name) const {
  std::string known;
  for (std::size_t i = 0; i < sensors_.size(); ++i) {
    if (sensors_[i].mount.name == name) return i;
    known += (known.empty() ? "" : ", ") + sensors_[i].mount.name;
  }
  throw std::invalid_argument("no sensor named '" + name + "' in scene '" + scene_.name +
                              "' (sensors: " + (known.empty() ? "none" : known) + ")");
}

Eigen::Isometry3d SimulatedSystem::sensor_pose(std::size_t i) const {
  std::shared_lock lock(mu_);
  return sensors_.at(i).mount.T_world_sensor;
}

void SimulatedSystem::set_sensor_pose(std::size_t i, const Eigen::Isometry3d& T) {
  std::unique_lock lock(mu_);
  sensors_.at(i).mount.T_world_sensor = T;
  scene_.sensors.at(i).T_world_sensor = T;
}

void SimulatedSystem::set_object_pose(ObjectId id, const Eigen::Isometry3d& T) {
  std::unique_lock lock(mu_);
  scene_.world.set_pose(id, T);
}

void SimulatedSystem::set_emitting(std::size_t i, bool on, double t) {
  std::unique_lock lock(mu_);
  auto& s = sensors_.at(i);
  if (on) {
    s.train_start = t;
    if (s.on.empty() || std::isfinite(s.on.back().second)) s.on.emplace_back(t, kInf);
  } else if (!s.on.empty() && !std::isfinite(s.on.back().second)) {
    s.on.back().second = t;
  }
  // Old intervals no longer matter to anyone's set.
  while (s.on.size() > 64) s.on.erase(s.on.begin());
}

SensorSet SimulatedSystem::measure(std::size_t i, double t_start, std::span<const int> pulses, std::uint64_t index,
                                   bool laser_on) {
  std::shared_lock lock(mu_);
  const SensorState& me = sensors_.at(i);
  const double t_end = t_start + pulses.back() / me.pulse_rate_hz;
  std::vector<ForeignEmitter> others;
  for (std::size_t j = 0; j < sensors_.size(); ++j) {
    if (j == i) continue;
    const SensorState& o = sensors_[j];
    bool overlaps = false;
    for (const auto& [a, b] : o.on) overlaps = overlaps || (a < t_end && b > t_start);
    if (!overlaps) continue;
    ForeignEmitter f;
    f.name = o.mount.name;
    f.T_world_sensor = o.mount.T_world_sensor;
    f.emitter = o.mount.params.emitter;
    f.first_pulse_s = o.train_start;
    f.pulse_rate_hz = o.pulse_rate_hz;
    f.on_intervals = o.on;
    others.push_back(std::move(f));
  }
  MeasureOptions opt;
  opt.laser_on = laser_on;
  // Crosstalk timing runs on the shared clock: shared = sensor time - power-on age.
  opt.clock_offset_s = -options_.power_on_age_s;
  return me.model.measure(scene_.world, me.mount.T_world_sensor, sensor_time(t_start), pulses, index, others, opt);
}

}  // namespace tinyline::sim
