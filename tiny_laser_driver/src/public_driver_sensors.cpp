// SPDX-License-Identifier: Apache-2.0
#include <tiny_laser_driver/public_driver_sensors.hpp>

#include <array>

namespace tinyline::tiny_laser_driver {

namespace {

struct PublicSensor {
  const char* name;
  std::array<double, 7> poly;     // distance_cm, highest power of k = b / (a + b) first
  std::array<double, 7> offsets;  // added to poly by the public driver
  double stable_temperature_decic;
  double temperature_sensi_cm_per_decic;
};

// Transcribed from the public driver.
constexpr PublicSensor kSensors[] = {
    {"R",
     {1.648001258107309e+06, -5.305835891559632e+06, 7.127857366587162e+06, -5.110547144753641e+06,
      2.060999435889212e+06, -4.423848603771256e+05, 3.937815633389474e+04},
     {0, 0, 0, 0, 0, -15, 9},
     480,
     0.09623},
    {"J",
     {-7.030060013434869e+07, 2.340939930305397e+08, -3.244894105718181e+08, 2.396546574907680e+08,
      -9.946220641072804e+07, 2.199337693620224e+07, -2.024360412459942e+06},
     {0, 0, 0, 0, 0, 0, 6},
     460,
     0.05623},
    {"S",
     {2.004878860926888e+09, -6.155609773756969e+09, 7.872203128922240e+09, -5.367517768838326e+09,
      2.057909512255952e+09, -4.206589491410656e+08, 3.581571264948885e+07},
     {0, 0, 0, 0, 0, 0, 6},
     470,
     0.09623},
    {"K",
     {2.147918234375362e+06, -7.736068312640203e+06, 1.154494186428487e+07, -9.137795412258314e+06,
      4.045684724836031e+06, -9.494901699902674e+05, 9.219599710241470e+04},
     {0, 0, 0, 0, 0, 0, 0},
     440,
     0.05623},
    {"T",
     {-6.539712337289967e+05, 2.522196790614386e+06, -3.966911268599921e+06, 3.266065347655729e+06,
      -1.487548484816432e+06, 3.563561476000117e+05, -3.519452184644648e+04},
     {0, 0, 0, 0, 0, 20, -3},
     460,
     0.05623},
};

}  // namespace

std::vector<std::string> public_driver_sensor_names() {
  std::vector<std::string> out;
  for (const auto& s : kSensors) out.emplace_back(s.name);
  return out;
}

std::optional<CalibrationModel> public_driver_calibration(const std::string& name) {
  for (const auto& s : kSensors) {
    if (name == s.name) {
      return CalibrationModel::from_public_driver(std::vector<double>(s.poly.begin(), s.poly.end()),
                                                  std::vector<double>(s.offsets.begin(), s.offsets.end()),
                                                  s.stable_temperature_decic, s.temperature_sensi_cm_per_decic);
    }
  }
  return std::nullopt;
}

}  // namespace tinyline::tiny_laser_driver
