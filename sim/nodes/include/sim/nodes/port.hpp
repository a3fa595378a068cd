// SPDX-License-Identifier: Apache-2.0
// The driver's `sim:SCENE.yaml[#sensor]` port: the simulator's virtual device
// started in-process and opened through its pseudo-terminal like a real
// port, registered into the driver's port-scheme registry.
#pragma once

namespace tinyline::sim {

/// Registers the "sim" scheme with the driver's port openers
/// (tiny_laser_driver/io/port.hpp). register_nodes() calls it; a test that
/// opens `sim:` ports without the node registry calls it itself. Idempotent.
void register_port_scheme();

}  // namespace tinyline::sim
