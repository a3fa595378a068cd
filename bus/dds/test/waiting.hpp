// SPDX-License-Identifier: Apache-2.0
// Waiting on conditions with deadlines (never sleeping): a log sink and an
// inbox that signal every arrival.
#pragma once

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <tinyline/bus/logging.hpp>

namespace tinyline::testing {

/// Everything a test waits for goes through one of these.
class Signal {
 public:
  void notify() {
    {
      std::lock_guard lk(mu_);
      ++version_;
    }
    cv_.notify_all();
  }
  /// Waits until pred() holds or the timeout. pred() is checked after every
  /// notify, and every few milliseconds for state nobody signals (counters).
  bool wait_for(const std::function<bool()>& pred, std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    std::unique_lock lk(mu_);
    for (;;) {
      const auto v = version_;
      lk.unlock();
      if (pred()) return true;
      lk.lock();
      const auto step = std::min(deadline, std::chrono::steady_clock::now() + std::chrono::milliseconds(5));
      cv_.wait_until(lk, step, [&] { return version_ != v; });
      if (std::chrono::steady_clock::now() >= deadline) {
        lk.unlock();
        return pred();
      }
    }
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::uint64_t version_ = 0;
};

/// A capture sink that signals each record.
class SignallingSink : public bus::CaptureSink {
 public:
  explicit SignallingSink(std::shared_ptr<Signal> s) : signal_(std::move(s)) {}
  void write(const bus::LogRecord& r) override {
    bus::CaptureSink::write(r);
    signal_->notify();
  }
  std::string dump() const {
    std::string s;
    for (const auto& r : records())
      s += "[" + std::string(bus::to_string(r.level)) + "] " + r.logger + ": " + r.text + "\n";
    return s;
  }

 private:
  std::shared_ptr<Signal> signal_;
};

/// Messages collected by a subscription callback, thread-safe.
template <class T>
class Inbox {
 public:
  explicit Inbox(std::shared_ptr<Signal> s) : signal_(std::move(s)) {}
  void push(T v) {
    {
      std::lock_guard lk(mu_);
      items_.push_back(std::move(v));
    }
    signal_->notify();
  }
  std::vector<T> items() const {
    std::lock_guard lk(mu_);
    return items_;
  }
  std::size_t size() const {
    std::lock_guard lk(mu_);
    return items_.size();
  }

 private:
  std::shared_ptr<Signal> signal_;
  mutable std::mutex mu_;
  std::vector<T> items_;
};

}  // namespace tinyline::testing
