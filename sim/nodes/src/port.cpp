// SPDX-License-Identifier: Apache-2.0
#include <sim/nodes/port.hpp>

#include <mutex>

#include <fmt/format.h>

#include <sim/virtual_device.hpp>
#include <sim/yaml_node.hpp>
#include <tinyline/common/files.hpp>
#include <tiny_laser_driver/io/port.hpp>

#include "parts.hpp"

namespace tinyline::sim {

namespace {

namespace io = tiny_laser_driver::io;

class SimOpener : public io::PortOpener {
 public:
  /// Checks the scene file now (the driver builds its opener when it is
  /// built, so a launch stops at the `port` line); starts nothing.
  SimOpener(std::string arg, io::PortOptions options) : arg_(std::move(arg)), options_(std::move(options)) {
    const std::string scene = VirtualDevice::parse_port("sim:" + arg_).first;
    try {
      files::check_input(scene, "scene", kMaxConfigFileBytes);
    } catch (const files::FileError& e) {
      throw std::invalid_argument(e.what());
    }
  }
  ~SimOpener() override {
    if (device_) device_->stop();
  }

  io::OpenResult open() override {
    if (!device_) {
      // Started on the first open (on_start), never in a constructor: no I/O before then.
      VirtualDeviceOptions o;
      o.baud = options_.serial.baud;
      o.laser_on = options_.laser_on_at_start;
      try {
        auto dev = VirtualDevice::from_port("sim:" + arg_, o);
        dev->start();
        device_ = std::move(dev);
      } catch (const std::exception& e) {
        return {nullptr,
                io::IoStatus::fail(io::IoError::kNotFound,
                                   fmt::format("sim:{}: cannot start the virtual device: {}", arg_, e.what()))};
      }
    }
    auto r = io::SerialPort::open(device_->path(), options_.serial);
    if (!r.status.ok()) r.status.message = fmt::format("sim:{}: {}", arg_, r.status.message);
    return {std::move(r.port), std::move(r.status)};
  }
  std::string describe() const override { return "sim:" + arg_; }

 private:
  std::string arg_;
  io::PortOptions options_;
  std::unique_ptr<VirtualDevice> device_;
};

}  // namespace

void register_port_scheme() {
  static std::once_flag once;
  std::call_once(once, [] {
    io::register_port_scheme("sim",
                             [](const std::string& arg, const io::PortOptions& o) -> std::unique_ptr<io::PortOpener> {
                               return std::make_unique<SimOpener>(arg, o);
                             });
  });
}

void nodes::register_port(bus::NodeRegistry&) { register_port_scheme(); }

}  // namespace tinyline::sim
