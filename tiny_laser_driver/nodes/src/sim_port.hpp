#pragma once

namespace tinyline::tiny_laser_driver::detail {

/// Registers the "sim" port scheme when the driver is built with the
/// simulator's virtual device (a no-op otherwise). Idempotent.
void register_sim_port_scheme();

}  // namespace tinyline::tiny_laser_driver::detail
