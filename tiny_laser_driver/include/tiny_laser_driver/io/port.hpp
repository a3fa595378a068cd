// SPDX-License-Identifier: Apache-2.0
// How the driver names its sensor, and what reopens it after a disconnect:
//
//   /dev/ttyUSB0      a serial port path (or a pty, or a stable symlink to one)
//   usb:A50285BI      the sensor whose USB serial number is A50285BI, found
//                     again (and its tty looked up again) at every reconnect
//   SCHEME:ARG        a scheme registered at run time: "sim:SCENE.yaml" (the
//                     simulator's virtual device, registered by the simulator's
//                     register_nodes(), which the `tinyline` tool calls),
//                     "mem:NAME" (an in-memory link, for tests and embedding)
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <tiny_laser_driver/io/byte_stream.hpp>
#include <tiny_laser_driver/io/serial_port.hpp>
#include <tiny_laser_driver/io/usb_discovery.hpp>
#include <tiny_laser_driver/protocol.hpp>

namespace tinyline::tiny_laser_driver::io {

struct PortOptions {
  SerialOptions serial;
  DiscoveryOptions discovery;
  /// For schemes that start a device (sim:): whether its laser starts on
  /// (off in sequence mode). What it streams is the device's business.
  bool laser_on_at_start = true;
};

/// Opens (and after a disconnect, reopens) one port.
class PortOpener {
 public:
  virtual ~PortOpener() = default;
  [[nodiscard]] virtual OpenResult open() = 0;
  /// What the spec names, for logs ("usb:A50285BI", "/dev/ttyUSB0").
  [[nodiscard]] virtual std::string describe() const = 0;
  /// Hardware id for diagnostics (serial number or path).
  [[nodiscard]] virtual std::string hardware_id() const { return describe(); }
};

using PortSchemeFactory = std::function<std::unique_ptr<PortOpener>(const std::string& arg, const PortOptions&)>;

/// Registers (or replaces) a scheme; thread-safe.
void register_port_scheme(const std::string& scheme, PortSchemeFactory factory);
void unregister_port_scheme(const std::string& scheme);
[[nodiscard]] std::vector<std::string> port_schemes();

/// Makes the opener for a port spec. Throws std::invalid_argument naming the
/// spec and the accepted forms (and the registered schemes) when it is malformed.
[[nodiscard]] std::unique_ptr<PortOpener> make_port_opener(const std::string& spec, const PortOptions& options = {});

/// Makes `link` reachable as "mem:NAME" (registers the "mem" scheme on first use).
void register_memory_link(const std::string& name, std::shared_ptr<MemoryLink> link);
void unregister_memory_link(const std::string& name);

}  // namespace tinyline::tiny_laser_driver::io
