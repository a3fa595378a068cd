// SPDX-License-Identifier: Apache-2.0
#include <tiny_laser_driver/io/port.hpp>

#include <map>
#include <mutex>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace tinyline::tiny_laser_driver::io {

namespace {

struct Registry {
  std::mutex mu;
  std::map<std::string, PortSchemeFactory> schemes;
  std::map<std::string, std::shared_ptr<MemoryLink>> links;
};
Registry& registry() {
  static Registry r;
  return r;
}

class PathOpener : public PortOpener {
 public:
  PathOpener(std::string path, SerialOptions o) : path_(std::move(path)), options_(o) {}
  OpenResult open() override {
    auto r = SerialPort::open(path_, options_);
    return {std::move(r.port), std::move(r.status)};
  }
  std::string describe() const override { return path_; }

 private:
  std::string path_;
  SerialOptions options_;
};

class UsbOpener : public PortOpener {
 public:
  UsbOpener(std::string serial, PortOptions o) : serial_(std::move(serial)), options_(std::move(o)) {
    options_.serial.sysfs_root = options_.discovery.sysfs_root;
  }
  OpenResult open() override {
    // Looked up at every (re)open: after a replug the tty may have a new name.
    const FoundTty found = find_sensor_tty(serial_, options_.discovery);
    if (!found.status.ok()) return {nullptr, found.status};
    auto r = SerialPort::open(found.tty, options_.serial);
    if (!r.status.ok()) r.status.message = fmt::format("usb:{} ({}): {}", serial_, found.tty, r.status.message);
    return {std::move(r.port), std::move(r.status)};
  }
  std::string describe() const override { return "usb:" + serial_; }
  std::string hardware_id() const override { return serial_; }

 private:
  std::string serial_;
  PortOptions options_;
};

class MemoryOpener : public PortOpener {
 public:
  explicit MemoryOpener(std::string name) : name_(std::move(name)) {}
  OpenResult open() override {
    std::shared_ptr<MemoryLink> link;
    {
      auto& r = registry();
      std::lock_guard lk(r.mu);
      if (auto it = r.links.find(name_); it != r.links.end()) link = it->second;
    }
    if (!link)
      return {nullptr, IoStatus::fail(IoError::kNotFound, fmt::format("mem:{}: no such in-memory link", name_))};
    return link->open();
  }
  std::string describe() const override { return "mem:" + name_; }

 private:
  std::string name_;
};

std::string accepted_forms() {
  std::string schemes;
  for (const auto& s : port_schemes()) {
    if (s != "usb") schemes += (schemes.empty() ? "" : ", ") + s + ":...";
  }
  return fmt::format("a device path (/dev/ttyUSB0), usb:SERIAL{}", schemes.empty() ? "" : ", or " + schemes);
}

}  // namespace

void register_port_scheme(const std::string& scheme, PortSchemeFactory factory) {
  auto& r = registry();
  std::lock_guard lk(r.mu);
  r.schemes[scheme] = std::move(factory);
}

void unregister_port_scheme(const std::string& scheme) {
  auto& r = registry();
  std::lock_guard lk(r.mu);
  r.schemes.erase(scheme);
}

std::vector<std::string> port_schemes() {
  auto& r = registry();
  std::lock_guard lk(r.mu);
  std::vector<std::string> out{"usb"};
  for (const auto& [k, v] : r.schemes) out.push_back(k);
  return out;
}

std::unique_ptr<PortOpener> make_port_opener(const std::string& spec, const PortOptions& options) {
  if (spec.empty()) throw std::invalid_argument("empty port: expected " + accepted_forms());
  if (spec.front() == '/' || spec.rfind("./", 0) == 0) return std::make_unique<PathOpener>(spec, options.serial);
  const auto colon = spec.find(':');
  if (colon == std::string::npos || colon == 0) {
    throw std::invalid_argument(fmt::format("port '{}': expected {}", spec, accepted_forms()));
  }
  const std::string scheme = spec.substr(0, colon);
  const std::string arg = spec.substr(colon + 1);
  if (arg.empty()) throw std::invalid_argument(fmt::format("port '{}': nothing after '{}:'", spec, scheme));
  if (scheme == "usb") return std::make_unique<UsbOpener>(arg, options);
  PortSchemeFactory factory;
  {
    auto& r = registry();
    std::lock_guard lk(r.mu);
    if (auto it = r.schemes.find(scheme); it != r.schemes.end()) factory = it->second;
  }
  if (!factory) {
    throw std::invalid_argument(
        fmt::format("port '{}': unknown scheme '{}'; expected {}", spec, scheme, accepted_forms()));
  }
  return factory(arg, options);
}

void register_memory_link(const std::string& name, std::shared_ptr<MemoryLink> link) {
  auto& r = registry();
  std::lock_guard lk(r.mu);
  r.links[name] = std::move(link);
  if (!r.schemes.count("mem")) {
    r.schemes["mem"] = [](const std::string& arg, const PortOptions&) -> std::unique_ptr<PortOpener> {
      return std::make_unique<MemoryOpener>(arg);
    };
  }
}

void unregister_memory_link(const std::string& name) {
  auto& r = registry();
  std::lock_guard lk(r.mu);
  r.links.erase(name);
}

}  // namespace tinyline::tiny_laser_driver::io
