// SPDX-License-Identifier: Apache-2.0
#include <tiny_laser_driver/nodes/register.hpp>

#include <tiny_laser_driver/nodes/laser_driver.hpp>
#include <tiny_laser_driver/nodes/raw_processor.hpp>

namespace tinyline::tiny_laser_driver {

void register_nodes(bus::NodeRegistry& registry) {
  registry.add<LaserDriver>("tiny_laser_driver", "laser_driver",
                            "tiny laser line sensor driver: serial/USB/simulated port to raw, calibrated and LaserScan "
                            "scans, with diagnostics and sequence-mode laser control");
  registry.add<RawProcessor>("tiny_laser_driver", "raw_processor",
                             "recorded raw scans to calibrated LineScan and LaserScan, as the driver makes them");
}

}  // namespace tinyline::tiny_laser_driver
