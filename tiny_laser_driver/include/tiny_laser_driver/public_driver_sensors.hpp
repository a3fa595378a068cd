// SPDX-License-Identifier: Apache-2.0
// The five real sensors whose calibrations the public driver ships
// (R, J, S, K, T), as calibration
// models, so a driver can run a real sensor with `calibration: public:K`.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <tiny_laser_driver/calibration.hpp>

namespace tinyline::tiny_laser_driver {

/// Names of the sensors the public driver knows ("R", "J", "S", "K", "T").
[[nodiscard]] std::vector<std::string> public_driver_sensor_names();
/// The public driver's calibration of sensor `name`; nullopt for an unknown name.
[[nodiscard]] std::optional<CalibrationModel> public_driver_calibration(const std::string& name);

}  // namespace tinyline::tiny_laser_driver
