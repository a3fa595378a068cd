#include "sim_rail_session.hpp"

#include <exception>

#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/recorder.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/registry.hpp>

#include <sim/nodes/register.hpp>
#include <sim/rail.hpp>
#include <sim/system.hpp>

namespace tinyline::tiny_laser_calibration::testing {

SimRailSessionResult record_sim_rail_session(const SimRailSession& s) {
  namespace bus = tinyline::bus;
  namespace bag = tinyline::bag;
  namespace sim = tinyline::sim;
  SimRailSessionResult out;
  try {
    if (s.distances_m.empty() || s.sets_per_distance < 1) throw std::invalid_argument("no rail positions or sets");
    // Hold the scene's shared system with our options: the sensor node gets the same one.
    sim::SystemOptions so;
    so.power_on_age_s = s.power_on_age_s;
    const auto system = sim::SimulatedSystem::shared(s.scene, so);
    const auto target = system->with_scene([&](const sim::Scene& sc) { return sc.world.find(s.target); });
    if (!target) throw std::invalid_argument(s.scene + ": no object named '" + s.target + "'");
    Eigen::Isometry3d pose = system->with_scene([&](const sim::Scene& sc) { return sc.world.object(*target).T_world_object; });
    const auto& params = system->sensor(0).params();
    const double period_s = params.acquisition.raw_pulses.back() / params.emitter.pulse_rate_hz;

    bus::ContextOptions co;
    co.clock = bus::ClockType::Sim;
    co.log_sink = std::make_shared<bus::CaptureSink>();
    auto ctx = bus::Context::create(co);
    const double t0 = 100.0;
    ctx->clock().set_sim_time(bus::Time::from_seconds(t0));
    bus::DeterministicExecutor ex(ctx->clock());
    bus::NodeRegistry registry;
    sim::register_nodes(registry);

    bag::RecorderOptions ro;
    ro.path = s.bag_path;
    ro.topics = {s.ns + "/raw_scan", s.ns + "/scan_truth"};
    bus::NodeOptions rec;
    rec.context = ctx;
    rec.name = "recorder";
    auto recorder = std::make_shared<bag::Recorder>(rec, ro);
    ex.add_node(recorder);

    bus::NodeOptions o;
    o.context = ctx;
    o.name = "laser";
    o.ns = s.ns;
    o.param("scene", s.scene).param("power_on_age_s", s.power_on_age_s);
    auto sensor = registry.create("sim", "virtual_sensor", o);
    ex.add_node(sensor);
    ex.spin_until_idle();

    // The sensor ticks every period from t0; move the target half a period
    // before the first set of each position so no set sees two positions.
    double t = t0 + 0.5 * period_s;
    for (double d : s.distances_m) {
      ex.advance_to(bus::Time::from_seconds(t));
      pose.translation().z() = d;
      system->set_object_pose(*target, pose);
      t += s.sets_per_distance * period_s;
    }
    ex.advance_to(bus::Time::from_seconds(t));
    ex.spin_until_idle();
    const auto status = recorder->stop();
    if (!status.ok()) throw std::runtime_error(status.str());
    out.dropped = recorder->stats().dropped;
    ex.remove_node(sensor);

    bag::Reader reader;
    if (auto st = reader.open(s.bag_path); !st.ok()) throw std::runtime_error(st.str());
    for (const auto& [id, ch] : reader.channels()) {
      std::uint64_t n = 0;
      const auto it = reader.summary().statistics.channel_message_counts.find(id);
      if (it != reader.summary().statistics.channel_message_counts.end()) n = it->second;
      if (ch.topic == s.ns + "/raw_scan") out.raw_scans += n;
      if (ch.topic == s.ns + "/scan_truth") out.truths += n;
    }
  } catch (const std::exception& e) {
    out.error = e.what();
  }
  return out;
}

RailConstants measure_rail_constants(const tinyline::sim::SensorParams& params) {
  namespace sim = tinyline::sim;
  sim::RailParams rp;
  rp.target_width_m = 4.0;
  sim::MeasureOptions off;
  off.laser_on = false;
  const int dark = params.lens.dark_pixels, n = params.lens.pixels;
  double spb = 0.0, spp = 0.0;
  {
    const sim::CalibrationRail rail(params, rp);
    const std::vector<int> schedule{100, 400, 700};
    for (int k = 0; k < 5; ++k) {
      const auto set = rail.measure(3600.0, schedule, 900000 + static_cast<std::uint64_t>(k), off);
      for (const auto& r : set.readouts) {
        for (int px = dark; px < n - dark; ++px) {
          spb += r.pulses * r.b[static_cast<std::size_t>(px)];
          spp += static_cast<double>(r.pulses) * r.pulses;
        }
      }
    }
  }
  double sa = 0.0, sb = 0.0;
  {
    sim::SensorParams lit = params;
    lit.environment.ambient_charge_per_pulse = 0.3;
    const sim::CalibrationRail lamp(lit, rp);
    for (int k = 0; k < 5; ++k) {
      const auto set = lamp.measure(3600.0, std::vector<int>{400}, 910000 + static_cast<std::uint64_t>(k), off);
      for (int px = dark; px < n - dark; ++px) {
        sa += set.readouts[0].a[static_cast<std::size_t>(px)];
        sb += set.readouts[0].b[static_cast<std::size_t>(px)];
      }
    }
  }
  return {spp > 0.0 ? spb / spp : 0.0, sa > 0.0 ? sb / sa : 1.0};
}

}  // namespace tinyline::tiny_laser_calibration::testing
