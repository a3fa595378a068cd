// SPDX-License-Identifier: Apache-2.0
// The parameter tables of the driver core's settings: each field's name in
// launch files, unit, range and meaning, described once
// (<tinyline/common/param_table.hpp>).
#pragma once

#include <tinyline/common/param_table.hpp>

#include "tiny_laser_driver/scan_processor.hpp"

namespace tinyline::tiny_laser_driver {

template <class S, class V>
requires common::SettingsOf<S, OpticsParams>
void for_each_param(S& p, V&& v) {
  v(p.focal_mm, {"focal_mm", "mm", 0.5, 100.0, "receiver lens focal length (3.6 or 8 shipped)"});
  v(p.sensor_length_mm, {"sensor_length_mm", "mm", 0.1, 100.0, "length of the 256 effective pixels"});
}

}  // namespace tinyline::tiny_laser_driver
