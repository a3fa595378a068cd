// SPDX-License-Identifier: Apache-2.0
#include <tiny_laser_driver/io/byte_stream.hpp>

#include <algorithm>
#include <utility>

#include <fmt/format.h>

namespace tinyline::tiny_laser_driver::io {

std::string_view to_string(IoError e) {
  switch (e) {
    case IoError::kNone: return "ok";
    case IoError::kNotFound: return "not_found";
    case IoError::kPermission: return "permission";
    case IoError::kBusy: return "busy";
    case IoError::kNotSerial: return "not_serial";
    case IoError::kBadSetting: return "bad_setting";
    case IoError::kDisconnected: return "disconnected";
    case IoError::kIo: return "io";
  }
  return "?";
}

common::StatusCode status_code(IoError e) {
  switch (e) {
    case IoError::kNone: return common::StatusCode::Ok;
    case IoError::kNotFound: return common::StatusCode::NotFound;
    case IoError::kBadSetting:
    case IoError::kNotSerial: return common::StatusCode::InvalidArgument;
    case IoError::kPermission:
    case IoError::kBusy: return common::StatusCode::OpenFailed;
    case IoError::kDisconnected:
    case IoError::kIo: break;
  }
  return common::StatusCode::ReadFailed;
}

struct MemoryLink::State {
  mutable std::mutex mu;
  std::condition_variable cv;
  std::deque<std::uint8_t> to_host;
  std::vector<std::uint8_t> from_host;
  bool plugged = true;
  std::uint64_t generation = 0;  // bumped on unplug: host sides of older generations are dead
  bool host_open = false;
  bool interrupted = false;
  int opens = 0;
};

namespace {

class MemoryHost : public ByteStream {
 public:
  MemoryHost(std::shared_ptr<MemoryLink::State> s, std::uint64_t generation, std::string name, double baud)
      : s_(std::move(s)), generation_(generation), name_(std::move(name)), baud_(baud) {}
  ~MemoryHost() override {
    std::lock_guard lk(s_->mu);
    if (s_->generation == generation_) s_->host_open = false;
  }

  ReadResult read(std::span<std::uint8_t> buf, std::chrono::milliseconds timeout) override {
    std::unique_lock lk(s_->mu);
    auto ready = [&] { return !s_->to_host.empty() || s_->generation != generation_ || s_->interrupted; };
    if (!ready() && timeout.count() > 0) s_->cv.wait_for(lk, timeout, ready);
    s_->interrupted = false;
    if (!s_->to_host.empty() && (s_->generation == generation_ || !s_->plugged)) {
      const std::size_t n = std::min(buf.size(), s_->to_host.size());
      std::copy_n(s_->to_host.begin(), n, buf.begin());
      s_->to_host.erase(s_->to_host.begin(), s_->to_host.begin() + static_cast<std::ptrdiff_t>(n));
      return {n, {}};
    }
    if (s_->generation != generation_) {
      return {0, IoStatus::fail(IoError::kDisconnected, fmt::format("{}: device unplugged", name_))};
    }
    return {0, {}};
  }

  IoStatus write(std::span<const std::uint8_t> bytes) override {
    std::lock_guard lk(s_->mu);
    if (s_->generation != generation_) {
      return IoStatus::fail(IoError::kDisconnected, fmt::format("{}: device unplugged", name_));
    }
    s_->from_host.insert(s_->from_host.end(), bytes.begin(), bytes.end());
    return {};
  }

  void interrupt() override {
    {
      std::lock_guard lk(s_->mu);
      s_->interrupted = true;
    }
    s_->cv.notify_all();
  }
  double baud() const override { return baud_; }
  std::string describe() const override { return fmt::format("{} (in-memory link) at {:.0f} baud", name_, baud_); }

 private:
  std::shared_ptr<MemoryLink::State> s_;
  std::uint64_t generation_;
  std::string name_;
  double baud_;
};

}  // namespace

MemoryLink::MemoryLink(std::string name, double baud)
    : name_(std::move(name)), baud_(baud), state_(std::make_shared<State>()) {}

std::shared_ptr<MemoryLink> MemoryLink::create(std::string name, double baud) {
  return std::make_shared<MemoryLink>(std::move(name), baud);
}

OpenResult MemoryLink::open() {
  std::lock_guard lk(state_->mu);
  if (!state_->plugged) {
    return {nullptr, IoStatus::fail(IoError::kNotFound, fmt::format("{}: no device (unplugged)", name_))};
  }
  if (state_->host_open) {
    return {nullptr, IoStatus::fail(IoError::kBusy, fmt::format("{}: already open", name_))};
  }
  state_->host_open = true;
  state_->interrupted = false;
  ++state_->opens;
  state_->cv.notify_all();
  return {std::make_unique<MemoryHost>(state_, state_->generation, name_, baud_), {}};
}

void MemoryLink::push(std::span<const std::uint8_t> bytes) {
  {
    std::lock_guard lk(state_->mu);
    // Like a tty nobody has open: bytes sent while unplugged or unopened are lost.
    if (!state_->plugged || !state_->host_open) return;
    state_->to_host.insert(state_->to_host.end(), bytes.begin(), bytes.end());
  }
  state_->cv.notify_all();
}

std::vector<std::uint8_t> MemoryLink::take_written() {
  std::lock_guard lk(state_->mu);
  return std::exchange(state_->from_host, {});
}

void MemoryLink::unplug(bool keep_queued) {
  {
    std::lock_guard lk(state_->mu);
    state_->plugged = false;
    ++state_->generation;
    state_->host_open = false;
    if (!keep_queued) state_->to_host.clear();
  }
  state_->cv.notify_all();
}

void MemoryLink::replug() {
  std::lock_guard lk(state_->mu);
  state_->plugged = true;
  state_->to_host.clear();
}

bool MemoryLink::plugged() const {
  std::lock_guard lk(state_->mu);
  return state_->plugged;
}

std::size_t MemoryLink::queued() const {
  std::lock_guard lk(state_->mu);
  return state_->to_host.size();
}

bool MemoryLink::wait_for_host(std::chrono::milliseconds timeout) {
  std::unique_lock lk(state_->mu);
  return state_->cv.wait_for(lk, timeout, [&] { return state_->host_open; });
}

int MemoryLink::opens() const {
  std::lock_guard lk(state_->mu);
  return state_->opens;
}

}  // namespace tinyline::tiny_laser_driver::io
