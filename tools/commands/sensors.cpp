// tinyline sensors: lists the tiny laser sensors attached over USB (their
// FTDI adapters), with the port spec to give the driver and whether this
// user can open them.
#if __has_include(<tiny_laser_driver/io/usb_discovery.hpp>)
#include <fmt/format.h>

#include <tiny_laser_driver/io/usb_discovery.hpp>
#include <tinyline/tools/command.hpp>

#include "../src/args.hpp"

namespace tinyline::tools {
namespace {

namespace io = tiny_laser_driver::io;

int cmd_sensors(const std::vector<std::string>& argv) {
  Args a(argv, {"--vid-pid", "--sysfs-root", "--dev-root"}, {"--all", "--no-libusb", "--help", "-h"});
  if (a.flag("--help") || a.flag("-h") || !a.positional().empty()) {
    fmt::print(
        "usage: tinyline sensors [--vid-pid 0403:6001] [--all] [--no-libusb] [--sysfs-root DIR] [--dev-root DIR]\n\n"
        "Lists the sensors attached over USB: their FTDI FT232R adapters (VID:PID 0403:6001 unless\n"
        "--vid-pid says otherwise; --all lists every USB serial adapter), the port to give the driver\n"
        "(usb:SERIAL), the tty, the USB socket, the kernel driver, and whether you can open it.\n"
        "--sysfs-root/--dev-root read a different tree (tests, containers with a mounted /sys).\n");
    return a.positional().empty() ? 0 : 2;
  }
  io::DiscoveryOptions o;
  if (auto v = a.value("--vid-pid")) {
    const auto vp = io::parse_vid_pid(*v);
    if (!vp) throw UsageError("--vid-pid expects VID:PID in hex, e.g. 0403:6001, got '" + *v + "'");
    o.vendor_id = vp->first;
    o.product_id = vp->second;
  }
  o.any_device = a.flag("--all");
  o.use_libusb = !a.flag("--no-libusb");
  if (auto v = a.value("--sysfs-root")) o.sysfs_root = *v;
  if (auto v = a.value("--dev-root")) o.dev_root = *v;
  const auto found = io::discover_usb_serial(o);
  fmt::print("{}", io::format_sensor_list(found, o));
  return 0;
}

const CommandRegistration kSensors{"sensors", "list the laser sensors attached over USB", &cmd_sensors};

}  // namespace
}  // namespace tinyline::tools
#endif
