// SPDX-License-Identifier: Apache-2.0
#include <tiny_laser_driver/io/usb_discovery.hpp>

#include <algorithm>
#include <charconv>
#include <filesystem>
#include <fstream>
#include <map>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>

#include <tiny_laser_driver/io/serial_port.hpp>

#if TINYLINE_HAVE_LIBUSB
#include <libusb.h>
#endif

namespace fs = std::filesystem;

namespace tinyline::tiny_laser_driver::io {

namespace {

std::string read_line(const fs::path& p) {
  std::ifstream f(p);
  std::string s;
  if (!f || !std::getline(f, s)) return "";
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r' || s.back() == ' ')) s.pop_back();
  return s;
}

std::optional<std::uint16_t> read_hex16(const fs::path& p) {
  const std::string s = read_line(p);
  unsigned v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v, 16);
  if (s.empty() || r.ec != std::errc{} || r.ptr != s.data() + s.size() || v > 0xFFFF) return std::nullopt;
  return static_cast<std::uint16_t>(v);
}

fs::path usb_devices_dir(const DiscoveryOptions& o) { return fs::path(o.sysfs_root) / "sys/bus/usb/devices"; }

// The tty bound to one of the device's interfaces: <dev>/<dev>:C.I/ttyUSBn
// (usb-serial drivers such as ftdi_sio) or <dev>/<dev>:C.I/tty/ttyACMn (cdc_acm).
std::string find_tty(const fs::path& dev_dir, const std::string& dev_name) {
  std::error_code ec;
  std::vector<std::string> found;
  for (const auto& iface : fs::directory_iterator(dev_dir, ec)) {
    const std::string iname = iface.path().filename().string();
    if (iname.rfind(dev_name + ":", 0) != 0) continue;
    std::error_code ec2;
    for (const auto& e : fs::directory_iterator(iface.path(), ec2)) {
      const std::string n = e.path().filename().string();
      if (n.rfind("ttyUSB", 0) == 0) found.push_back(n);
      if (n == "tty") {
        std::error_code ec3;
        for (const auto& t : fs::directory_iterator(e.path(), ec3)) found.push_back(t.path().filename().string());
      }
    }
  }
  std::sort(found.begin(), found.end());
  return found.empty() ? "" : found.front();
}

std::optional<UsbSerialDevice> read_device(const DiscoveryOptions& o, const std::string& name) {
  const fs::path dir = usb_devices_dir(o) / name;
  const auto vid = read_hex16(dir / "idVendor");
  const auto pid = read_hex16(dir / "idProduct");
  if (!vid || !pid) return std::nullopt;
  UsbSerialDevice d;
  d.usb_path = name;
  d.vendor_id = *vid;
  d.product_id = *pid;
  d.serial = read_line(dir / "serial");
  d.manufacturer = read_line(dir / "manufacturer");
  d.product = read_line(dir / "product");
  const std::string tty = find_tty(dir, name);
  if (!tty.empty()) {
    d.tty = (fs::path(o.dev_root) / tty).string();
    std::error_code ec;
    const auto drv = fs::read_symlink(fs::path(o.sysfs_root) / "sys/class/tty" / tty / "device/driver", ec);
    if (!ec) d.driver = drv.filename().string();
  }
  return d;
}

bool wanted(const DiscoveryOptions& o, const UsbSerialDevice& d) {
  if (o.any_device) return !d.tty.empty();
  return d.vendor_id == o.vendor_id && d.product_id == o.product_id;
}

// Device directories are named bus-port[.port...] ("1-1.2"); interfaces carry
// a colon and root hubs are "usbN".
bool is_device_name(const std::string& n) {
  return n.find(':') == std::string::npos && n.find('-') != std::string::npos && n.rfind("usb", 0) != 0;
}

Discovery discover_sysfs(const DiscoveryOptions& o, std::string note) {
  Discovery out;
  out.backend = "sysfs";
  out.note = std::move(note);
  std::error_code ec;
  const fs::path base = usb_devices_dir(o);
  if (!fs::exists(base, ec)) {
    if (!out.note.empty()) out.note += "; ";
    out.note += fmt::format("{} does not exist (no USB in this machine or container?)", base.string());
    return out;
  }
  for (const auto& e : fs::directory_iterator(base, ec)) {
    const std::string n = e.path().filename().string();
    if (!is_device_name(n)) continue;
    if (auto d = read_device(o, n); d && wanted(o, *d)) out.devices.push_back(std::move(*d));
  }
  std::sort(out.devices.begin(), out.devices.end(),
            [](const UsbSerialDevice& a, const UsbSerialDevice& b) { return a.usb_path < b.usb_path; });
  return out;
}

#if TINYLINE_HAVE_LIBUSB
std::optional<Discovery> discover_libusb(const DiscoveryOptions& o, std::string& note) {
  libusb_context* ctx = nullptr;
  if (const int r = libusb_init(&ctx); r != 0) {
    note = fmt::format("libusb unavailable ({})", libusb_error_name(r));
    return std::nullopt;
  }
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx, &list);
  if (n < 0) {
    note = fmt::format("libusb cannot list devices ({})", libusb_error_name(static_cast<int>(n)));
    libusb_exit(ctx);
    return std::nullopt;
  }
  Discovery out;
  out.backend = "libusb";
  for (ssize_t i = 0; i < n; ++i) {
    libusb_device* dev = list[i];
    libusb_device_descriptor desc{};
    if (libusb_get_device_descriptor(dev, &desc) != 0) continue;
    if (!o.any_device && (desc.idVendor != o.vendor_id || desc.idProduct != o.product_id)) continue;
    std::uint8_t ports[8];
    const int np = libusb_get_port_numbers(dev, ports, 8);
    if (np <= 0) continue;  // a root hub
    std::string name = fmt::format("{}-{}", libusb_get_bus_number(dev), ports[0]);
    for (int k = 1; k < np; ++k) name += fmt::format(".{}", ports[k]);
    // Strings and the tty come from sysfs (no permission needed); libusb
    // would have to open the device for the strings.
    UsbSerialDevice d;
    if (auto s = read_device(o, name)) d = std::move(*s);
    d.usb_path = name;
    d.vendor_id = desc.idVendor;
    d.product_id = desc.idProduct;
    if (d.serial.empty() && desc.iSerialNumber != 0) {
      libusb_device_handle* h = nullptr;
      if (libusb_open(dev, &h) == 0) {
        unsigned char buf[128];
        const int len = libusb_get_string_descriptor_ascii(h, desc.iSerialNumber, buf, sizeof buf);
        if (len > 0) d.serial.assign(reinterpret_cast<const char*>(buf), static_cast<std::size_t>(len));
        libusb_close(h);
      }
    }
    if (wanted(o, d)) out.devices.push_back(std::move(d));
  }
  libusb_free_device_list(list, 1);
  libusb_exit(ctx);
  std::sort(out.devices.begin(), out.devices.end(),
            [](const UsbSerialDevice& a, const UsbSerialDevice& b) { return a.usb_path < b.usb_path; });
  return out;
}
#endif

}  // namespace

std::optional<std::pair<std::uint16_t, std::uint16_t>> parse_vid_pid(const std::string& text) {
  const auto colon = text.find(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 >= text.size()) return std::nullopt;
  unsigned v = 0, p = 0;
  const char* b = text.data();
  const auto r1 = std::from_chars(b, b + colon, v, 16);
  const auto r2 = std::from_chars(b + colon + 1, b + text.size(), p, 16);
  if (r1.ec != std::errc{} || r1.ptr != b + colon || r2.ec != std::errc{} || r2.ptr != b + text.size()) {
    return std::nullopt;
  }
  if (v > 0xFFFF || p > 0xFFFF) return std::nullopt;
  return std::make_pair(static_cast<std::uint16_t>(v), static_cast<std::uint16_t>(p));
}

Discovery discover_usb_serial(const DiscoveryOptions& options) {
  std::string note;
#if TINYLINE_HAVE_LIBUSB
  if (options.use_libusb && options.sysfs_root == "/") {
    if (auto d = discover_libusb(options, note)) return std::move(*d);
  }
#else
  if (options.use_libusb && options.sysfs_root == "/") note = "built without libusb";
#endif
  return discover_sysfs(options, std::move(note));
}

FoundTty find_sensor_tty(const std::string& serial, const DiscoveryOptions& options) {
  FoundTty out;
  const Discovery found = discover_usb_serial(options);
  std::vector<std::string> others;
  for (const auto& d : found.devices) {
    if (d.serial == serial) {
      out.device = d;
      if (d.tty.empty()) {
        out.status = IoStatus::fail(
            IoError::kNotFound,
            fmt::format("usb:{}: the sensor is attached (USB {}) but no serial driver is bound to it: load the "
                        "FTDI driver (`sudo modprobe ftdi_sio`)",
                        serial, d.usb_path));
        return out;
      }
      out.tty = d.tty;
      return out;
    }
    others.push_back(d.serial.empty() ? "(no serial number) at " + d.usb_path : d.serial);
  }
  std::string attached = others.empty() ? "none attached" : "attached: " + fmt::format("{}", fmt::join(others, ", "));
  out.status = IoStatus::fail(
      IoError::kNotFound,
      fmt::format("usb:{}: no sensor with that serial number ({:04x}:{:04x} adapters {}; found with {}{}). Check the "
                  "cable; `tinyline sensors` lists what is attached",
                  serial, options.vendor_id, options.product_id, attached, found.backend,
                  found.note.empty() ? "" : ", " + found.note));
  return out;
}

std::string tty_access(const UsbSerialDevice& d) {
  if (d.tty.empty()) return "no serial driver bound (sudo modprobe ftdi_sio)";
  const int fd = ::open(d.tty.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    if (err == EACCES || err == EPERM) {
      return "no permission: add your user to the dialout group or install the udev rule (see below)";
    }
    if (err == EBUSY) return "in use by another process";
    return open_error_status(err, d.tty).message;
  }
  const bool busy = ::flock(fd, LOCK_EX | LOCK_NB) != 0;
  ::close(fd);
  return busy ? "in use by another process" : "ready";
}

std::string format_sensor_list(const Discovery& d, const DiscoveryOptions& o) {
  std::string out;
  const std::string what = o.any_device ? std::string("USB serial adapters")
                                        : fmt::format("{:04x}:{:04x} adapters", o.vendor_id, o.product_id);
  if (d.devices.empty()) {
    out += fmt::format("no {} found (searched with {}{}).\n", what, d.backend, d.note.empty() ? "" : "; " + d.note);
    out +=
        "Check the cable; a sensor shows up as an FTDI FT232R (0403:6001). `dmesg | tail` shows what the kernel saw.\n";
    return out;
  }
  out += fmt::format("{:<22} {:<14} {:<9} {:<9} {:<9} {}\n", "PORT", "TTY", "USB", "VID:PID", "DRIVER", "ACCESS");
  bool permission = false;
  for (const auto& dev : d.devices) {
    const std::string port = dev.serial.empty() ? dev.tty : "usb:" + dev.serial;
    const std::string access = tty_access(dev);
    permission = permission || access.rfind("no permission", 0) == 0;
    out += fmt::format("{:<22} {:<14} {:<9} {:04x}:{:04x} {:<9} {}\n", port.empty() ? "-" : port,
                       dev.tty.empty() ? "-" : dev.tty, dev.usb_path, dev.vendor_id, dev.product_id,
                       dev.driver.empty() ? "-" : dev.driver, access);
  }
  out += fmt::format("({} found with {}; give the driver `port: usb:SERIAL` to follow a sensor across sockets)\n",
                     d.devices.size(), d.backend);
  if (permission) {
    out +=
        "No permission: `sudo usermod -aG dialout $USER` (then log in again), or install "
        "tiny_laser_driver/config/99-tinyline-laser.rules into /etc/udev/rules.d/.\n";
  }
  return out;
}

}  // namespace tinyline::tiny_laser_driver::io
