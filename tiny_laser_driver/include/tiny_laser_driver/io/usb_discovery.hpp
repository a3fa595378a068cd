// SPDX-License-Identifier: Apache-2.0
// Finding the sensor's USB-UART adapter: by VID:PID (the FT232R's 0403:6001
// by default) and serial number, mapped to its tty through sysfs.
//
// Enumeration uses libusb when it is available and working (device
// descriptors need no permission), and sysfs otherwise; the tty always comes
// from sysfs (the kernel's usb-serial binding). Every file is read under a
// root directory, so tests point it at a fake tree.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <tiny_laser_driver/io/byte_stream.hpp>

namespace tinyline::tiny_laser_driver::io {

inline constexpr std::uint16_t kFtdiVendorId = 0x0403;
inline constexpr std::uint16_t kFt232rProductId = 0x6001;

struct UsbSerialDevice {
  std::string usb_path;  ///< bus-port path, e.g. "1-1.2" (stable while it stays in that socket)
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::string serial;  ///< USB serial number (an FTDI's is unique, e.g. "A50285BI")
  std::string manufacturer;
  std::string product;
  std::string tty;     ///< e.g. "/dev/ttyUSB0"; empty when no serial driver is bound
  std::string driver;  ///< kernel driver of the tty ("ftdi_sio"), may be empty
};

struct DiscoveryOptions {
  std::uint16_t vendor_id = kFtdiVendorId;
  std::uint16_t product_id = kFt232rProductId;
  bool any_device = false;        ///< list every USB serial adapter, whatever its VID:PID
  std::string sysfs_root = "/";   ///< where sys/ lives (tests: a fake tree)
  std::string dev_root = "/dev";  ///< where tty nodes live (tests: a directory of symlinks)
  /// Enumerate with libusb when built with it and sysfs_root is "/".
  bool use_libusb = true;
};

struct Discovery {
  std::vector<UsbSerialDevice> devices;  ///< sorted by usb_path
  std::string backend;                   ///< "libusb" or "sysfs"
  std::string note;                      ///< why a backend was not usable, if any
};

/// Every attached adapter matching the options.
[[nodiscard]] Discovery discover_usb_serial(const DiscoveryOptions& options = {});

/// Parses "0403:6001" (hex); nullopt on anything else.
[[nodiscard]] std::optional<std::pair<std::uint16_t, std::uint16_t>> parse_vid_pid(const std::string& text);

/// The tty of the sensor with serial number `serial`, or a status saying
/// which sensors are attached instead / that the serial driver is missing.
struct FoundTty {
  std::string tty;
  UsbSerialDevice device;
  IoStatus status;
};
[[nodiscard]] FoundTty find_sensor_tty(const std::string& serial, const DiscoveryOptions& options = {});

/// Whether this user can open a sensor's tty now: "ready", or what stands in
/// the way and what to do (no driver bound, no permission, in use).
[[nodiscard]] std::string tty_access(const UsbSerialDevice& d);

/// The listing `tinyline sensors` prints: one line per adapter with the port
/// spec to use, its tty, USB path and access; or why nothing was found.
[[nodiscard]] std::string format_sensor_list(const Discovery& d, const DiscoveryOptions& options);

}  // namespace tinyline::tiny_laser_driver::io
