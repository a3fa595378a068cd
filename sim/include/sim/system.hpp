// SPDX-License-Identifier: Apache-2.0
// A running simulation: one scene, its sensors, one shared clock, and the
// record of who emitted when (for crosstalk). Several virtual devices (one
// per sensor) share a system; their threads call it concurrently.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <vector>

#include <sim/scene.hpp>
#include <sim/tof_sensor.hpp>

namespace tinyline::sim {

struct SystemOptions {
  /// Sensor time at system start [s]: 0 is a cold power-on (the warm-up of
  /// 3.3.4 happens live); 3600 starts warm.
  double power_on_age_s = 3600.0;
  /// Spread of the sensors' pulse clocks [ppm rms] (crosstalk beats with it).
  double clock_ppm_sd = 20.0;
};

class SimulatedSystem {
 public:
  explicit SimulatedSystem(Scene scene, SystemOptions options = {});
  /// Loads a scene file; throws ConfigError.
  static std::shared_ptr<SimulatedSystem> from_file(const std::string& scene_path, SystemOptions options = {});
  /// The one system of this process for a scene file (made on first use, kept
  /// while anyone holds it): a driver's in-process device and the scene-truth
  /// node then share one world, one clock and one crosstalk record.
  static std::shared_ptr<SimulatedSystem> shared(const std::string& scene_path, SystemOptions options = {});

  /// Seconds since the system started (steady clock): the shared time base.
  [[nodiscard]] double now() const;
  [[nodiscard]] double sensor_time(double shared_s) const { return shared_s + options_.power_on_age_s; }
  /// For nodes on a bus clock: the bus time [s] that is shared time 0 for
  /// this system (set by the first caller, so every node agrees). Shared
  /// times stay small, keeping nanosecond resolution for crosstalk timing.
  double bus_epoch(double bus_time_s);
  /// Wall-clock time [s since the epoch] of a shared time (for message stamps).
  [[nodiscard]] double wall_time(double shared_s) const { return wall0_ + shared_s; }
  [[nodiscard]] const std::string& scene_name() const { return scene_.name; }

  [[nodiscard]] std::size_t sensor_count() const { return sensors_.size(); }
  /// Index of a sensor by name; throws std::invalid_argument naming the known ones.
  [[nodiscard]] std::size_t sensor_index(const std::string& name) const;
  [[nodiscard]] const std::string& sensor_name(std::size_t i) const { return sensors_.at(i).mount.name; }
  [[nodiscard]] const TofLineSensor& sensor(std::size_t i) const { return sensors_.at(i).model; }
  [[nodiscard]] Eigen::Isometry3d sensor_pose(std::size_t i) const;
  [[nodiscard]] double pulse_rate_hz(std::size_t i) const { return sensors_.at(i).pulse_rate_hz; }

  /// Moves a sensor or an object (thread-safe; takes effect from the next set).
  void set_sensor_pose(std::size_t i, const Eigen::Isometry3d& T_world_sensor);
  void set_object_pose(ObjectId id, const Eigen::Isometry3d& T_world_object);
  /// Runs `fn` with the scene locked for reading.
  template <class F>
  auto with_scene(F&& fn) const {
    std::shared_lock lock(mu_);
    return fn(scene_);
  }

  /// Records that sensor i's laser pulses from shared time t (true) or stops (false).
  void set_emitting(std::size_t i, bool on, double shared_s);
  /// Simulates one set of sensor i starting at shared time t_start (crosstalk
  /// from every other sensor that emits meanwhile).
  [[nodiscard]] SensorSet measure(std::size_t i, double t_start_shared, std::span<const int> pulses,
                                  std::uint64_t index, bool laser_on = true);

  /// Observers of every set any device of this system measures (called on the
  /// device's thread: keep them short). Returns an id for remove_observer().
  int add_observer(std::function<void(std::size_t sensor, const SensorSet& set)> fn);
  void remove_observer(int id);
  /// Devices call this with each set they measure.
  void notify(std::size_t sensor, const SensorSet& set);

 private:
  struct SensorState {
    SensorMount mount;
    TofLineSensor model;
    double pulse_rate_hz = 0.0;                 // nominal * (1 + ppm)
    std::vector<std::pair<double, double>> on;  // emission intervals (shared time), open end = +inf
    double train_start = 0.0;                   // start of the current pulse train
  };
  Scene scene_;
  SystemOptions options_;
  std::vector<SensorState> sensors_;
  std::chrono::steady_clock::time_point t0_;
  double wall0_ = 0.0;
  std::mutex epoch_mu_;
  std::optional<double> bus_epoch_;
  mutable std::shared_mutex mu_;
  std::mutex observers_mu_;
  std::vector<std::pair<int, std::function<void(std::size_t, const SensorSet&)>>> observers_;
  int next_observer_ = 1;
};

}  // namespace tinyline::sim
