// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/logging.hpp>

#include <unistd.h>

#include <cstdio>

#include <tinyline/bus/clock.hpp>

namespace tinyline::bus {

std::string_view to_string(LogLevel l) {
  switch (l) {
    case LogLevel::Debug: return "DEBUG";
    case LogLevel::Info: return "INFO";
    case LogLevel::Warn: return "WARN";
    case LogLevel::Error: return "ERROR";
  }
  return "?";
}

void StderrSink::write(const LogRecord& r) {
  static const bool color = isatty(2);
  const char* on = "";
  if (color) {
    on = r.level == LogLevel::Error ? "\033[31m" : r.level == LogLevel::Warn ? "\033[33m" : "";
  }
  const char* off = color && *on ? "\033[0m" : "";
  std::string line =
      fmt::format("{}[{}] [{:.3f}] [{}]: {}{}\n", on, to_string(r.level), r.stamp.seconds(), r.logger, r.text, off);
  std::lock_guard lk(mu_);
  std::fwrite(line.data(), 1, line.size(), stderr);
}

void CaptureSink::write(const LogRecord& r) {
  std::lock_guard lk(mu_);
  records_.push_back(r);
}

std::vector<LogRecord> CaptureSink::records() const {
  std::lock_guard lk(mu_);
  return records_;
}

bool CaptureSink::contains(LogLevel level, std::string_view needle) const {
  std::lock_guard lk(mu_);
  for (const auto& r : records_) {
    if (r.level == level && r.text.find(needle) != std::string::npos) return true;
  }
  return false;
}

void Logger::log(LogLevel level, std::string text) const {
  if (!enabled(level)) return;
  LogRecord r;
  r.level = level;
  r.stamp = clock_ ? clock_->now() : Time{};
  r.logger = name_;
  r.text = std::move(text);
  sink_->write(r);
}

}  // namespace tinyline::bus
