// SPDX-License-Identifier: Apache-2.0
// The driver's processing on the simulated sensor: raw sets from the
// simulator's calibration rail, through the wire encoding and the scan
// processor with the calibration the driver ships for that sensor, against the
// rail's ground truth. Fails when the shipped calibration no longer fits the
// simulated sensor (re-run config/calibration/make_sim_calibrations.sh).
#include <gtest/gtest.h>

#include <cmath>

#include <sim/rail.hpp>
#include <sim/sensor_params.hpp>

#include <tiny_laser_driver/nodes/laser_driver.hpp>

namespace tl = tinyline::tiny_laser_driver;
namespace sim = tinyline::sim;

namespace {

constexpr const char* kRefit =
    "\nIf the simulator's sensor physics changed (sim/include/sim/sensor_params.hpp, sim/config/sensors), re-fit the "
    "shipped calibrations: tiny_laser_driver/config/calibration/make_sim_calibrations.sh BUILD_DIR (README.md there)";

// What the firmware sends for a simulated set, parsed back as the driver would.
tl::RawSet to_wire_and_back(const sim::SensorSet& s) {
  std::vector<std::uint8_t> bytes;
  for (std::size_t k = 0; k < s.readouts.size(); ++k) {
    tl::RawFrame f;
    f.index = static_cast<std::uint16_t>(k);
    f.last = k + 1 == s.readouts.size();
    f.pulses = static_cast<std::uint16_t>(s.readouts[k].pulses);
    f.temperature_decic = static_cast<std::uint16_t>(std::lround(s.temperature_c * 10.0));
    for (std::size_t p = 0; p < tl::kPixels; ++p) {
      f.a[p] = static_cast<std::int16_t>(std::clamp(std::lround(10.0 * s.readouts[k].a[p]), -32768L, 32767L));
      f.b[p] = static_cast<std::int16_t>(std::clamp(std::lround(10.0 * s.readouts[k].b[p]), -32768L, 32767L));
    }
    tl::encode_raw_frame(f, bytes);
  }
  tl::Parser parser({s.readouts.size()});
  parser.feed(bytes);
  auto set = parser.next_set();
  if (!set) throw std::runtime_error("the parser did not give the set back");
  return std::move(*set);
}

struct Score {
  double rmse_cm = 0, bias_cm = 0, valid_share = 0;
};

Score score(const std::string& sensor_yaml, const std::string& calibration, double focal_mm,
            const std::vector<double>& distances) {
  const sim::SensorParams params = sim::load_sensor_params(sensor_yaml);
  sim::RailParams rp;
  rp.target_width_m = 4.0;
  sim::CalibrationRail rail(params, rp);
  tl::ScanProcessor proc(tl::load_calibration(calibration), tl::OpticsParams{focal_mm, 5.12});
  double se = 0, sum = 0;
  int n = 0, seen = 0;
  std::uint64_t index = 5'000'000;  // sets the calibration never saw
  for (double d : distances) {
    rail.set_target_distance(d);
    for (int k = 0; k < 4; ++k) {
      const auto s = rail.measure(1800.0 + k, params.acquisition.raw_pulses, index++);
      const auto out = proc.process(to_wire_and_back(s), 1800.0 + k);
      for (std::size_t p = tl::kDarkPixels; p < tl::kPixels - tl::kDarkPixels; ++p) {
        if (!std::isfinite(s.truth[p].range_m)) continue;
        ++seen;
        if (out.status[p] != tl::PixelStatus::kValid) continue;
        const double e = 100.0 * (out.distance_m[p] - s.truth[p].range_m);
        se += e * e;
        sum += e;
        ++n;
      }
    }
  }
  Score sc;
  sc.rmse_cm = std::sqrt(se / n);
  sc.bias_cm = sum / n;
  sc.valid_share = static_cast<double>(n) / seen;
  return sc;
}

}  // namespace

TEST(SimRail, DefaultCalibrationMeasuresTheSimulatedRailWithinItsError) {
  // Held-out RMSE of the shipped calibration: 3.28 cm (config/calibration/README.md).
  const Score s = score(TINYLINE_SOURCE_DIR "/sim/config/sensors/tiny_tof_8mm.yaml", "default", 8.0,
                        {0.3, 0.55, 0.8, 1.1, 1.4, 1.7});
  RecordProperty("rmse_cm", std::to_string(s.rmse_cm));
  EXPECT_LT(s.rmse_cm, 3.28 * 1.25) << "rmse " << s.rmse_cm << " cm" << kRefit;
  EXPECT_LT(std::abs(s.bias_cm), 1.0) << "bias " << s.bias_cm << " cm" << kRefit;
  EXPECT_GT(s.valid_share, 0.8) << "valid share " << s.valid_share;
}

TEST(SimRail, TheWideLensSensorHasItsOwnCalibration) {
  // Held-out RMSE 6.41 cm (README.md).
  const Score s = score(TINYLINE_SOURCE_DIR "/sim/config/sensors/tiny_tof_3p6mm.yaml",
                        TINYLINE_SOURCE_DIR "/tiny_laser_driver/config/calibration/sim_tiny_tof_3p6mm.yaml", 3.6,
                        {0.3, 0.55, 0.8, 1.1, 1.4});
  EXPECT_LT(s.rmse_cm, 6.41 * 1.25) << "rmse " << s.rmse_cm << " cm" << kRefit;
  EXPECT_LT(std::abs(s.bias_cm), 1.5) << "bias " << s.bias_cm << " cm" << kRefit;
  EXPECT_GT(s.valid_share, 0.6) << "valid share " << s.valid_share;
}
