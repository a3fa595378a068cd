// SPDX-License-Identifier: Apache-2.0
// Per-node logging. Every record carries the node's full name; a context has
// one sink (stderr by default, a capture sink in tests, a forwarding sink in
// the launch supervisor).
#pragma once

#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include <tinyline/bus/time.hpp>

namespace tinyline::bus {

enum class LogLevel { Debug = 0, Info = 1, Warn = 2, Error = 3 };

std::string_view to_string(LogLevel l);

struct LogRecord {
  LogLevel level = LogLevel::Info;
  Time stamp;          ///< context clock time
  std::string logger;  ///< node full name, e.g. /hand/laser_driver
  std::string text;
};

class LogSink {
 public:
  virtual ~LogSink() = default;
  virtual void write(const LogRecord& r) = 0;
  LogLevel min_level = LogLevel::Info;
};

/// "[WARN] [1700000000.123] [/hand/driver]: text" on stderr.
class StderrSink : public LogSink {
 public:
  void write(const LogRecord& r) override;

 private:
  std::mutex mu_;
};

/// Keeps every record; for tests.
class CaptureSink : public LogSink {
 public:
  CaptureSink() { min_level = LogLevel::Debug; }
  void write(const LogRecord& r) override;
  std::vector<LogRecord> records() const;
  bool contains(LogLevel level, std::string_view needle) const;

 private:
  mutable std::mutex mu_;
  std::vector<LogRecord> records_;
};

class Clock;

class Logger {
 public:
  Logger() = default;
  Logger(std::string name, std::shared_ptr<LogSink> sink, const Clock* clock)
      : name_(std::move(name)), sink_(std::move(sink)), clock_(clock) {}

  const std::string& name() const { return name_; }
  bool enabled(LogLevel l) const { return sink_ && l >= sink_->min_level; }

  void log(LogLevel level, std::string text) const;

  template <class... A>
  void debug(fmt::format_string<A...> f, A&&... a) const {
    if (enabled(LogLevel::Debug)) log(LogLevel::Debug, fmt::format(f, std::forward<A>(a)...));
  }
  template <class... A>
  void info(fmt::format_string<A...> f, A&&... a) const {
    if (enabled(LogLevel::Info)) log(LogLevel::Info, fmt::format(f, std::forward<A>(a)...));
  }
  template <class... A>
  void warn(fmt::format_string<A...> f, A&&... a) const {
    if (enabled(LogLevel::Warn)) log(LogLevel::Warn, fmt::format(f, std::forward<A>(a)...));
  }
  template <class... A>
  void error(fmt::format_string<A...> f, A&&... a) const {
    if (enabled(LogLevel::Error)) log(LogLevel::Error, fmt::format(f, std::forward<A>(a)...));
  }

 private:
  std::string name_;
  std::shared_ptr<LogSink> sink_;
  const Clock* clock_ = nullptr;
};

}  // namespace tinyline::bus
