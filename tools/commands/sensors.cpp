// SPDX-License-Identifier: Apache-2.0
// tinyline sensors: lists the tiny laser sensors attached over USB (their
// FTDI adapters), with the port spec to give the driver and whether this
// user can open them.
#if __has_include(<tiny_laser_driver/io/usb_discovery.hpp>)
#include <memory>

#include <fmt/format.h>

#include <tiny_laser_driver/io/usb_discovery.hpp>
#include <tinyline/tools/command.hpp>

#include "../src/parsing.hpp"

namespace tinyline::tools {
namespace {

namespace io = tiny_laser_driver::io;

struct SensorsArgs {
  std::string vid_pid;
  bool all = false;
  bool no_libusb = false;
  std::string sysfs_root;
  std::string dev_root;
};

int sensors(const SensorsArgs& a) {
  io::DiscoveryOptions o;
  if (!a.vid_pid.empty()) {
    const auto vp = io::parse_vid_pid(a.vid_pid);
    if (!vp) throw UsageError("--vid-pid expects VID:PID in hex, e.g. 0403:6001, got '" + a.vid_pid + "'");
    o.vendor_id = vp->first;
    o.product_id = vp->second;
  }
  o.any_device = a.all;
  o.use_libusb = !a.no_libusb;
  if (!a.sysfs_root.empty()) o.sysfs_root = a.sysfs_root;
  if (!a.dev_root.empty()) o.dev_root = a.dev_root;
  const auto found = io::discover_usb_serial(o);
  fmt::print("{}", io::format_sensor_list(found, o));
  return 0;
}

CommandRun setup_sensors(cli::App& cmd) {
  auto a = std::make_shared<SensorsArgs>();
  cmd.add_option("--vid-pid", a->vid_pid, "USB VID:PID of the adapter in hex (default 0403:6001, the FT232R)");
  cmd.add_flag("--all", a->all, "list every USB serial adapter");
  cmd.add_flag("--no-libusb", a->no_libusb, "read sysfs only");
  cmd.add_option("--sysfs-root", a->sysfs_root, "read this tree as /sys (tests, containers with a mounted /sys)");
  cmd.add_option("--dev-root", a->dev_root, "read this tree as /dev");
  cmd.footer(
      "Lists the sensors attached over USB: their FTDI FT232R adapters, the port to give the driver\n"
      "(usb:SERIAL), the tty, the USB socket, the kernel driver, and whether you can open it.");
  return [a] { return sensors(*a); };
}

const CommandRegistration kSensors{"sensors", "list the laser sensors attached over USB", &setup_sensors};

}  // namespace
}  // namespace tinyline::tools
#endif
