// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/logging.hpp>

#include <unistd.h>

#include <cstdio>
#include <shared_mutex>
#include <utility>
#include <vector>

#include <tinyline/bus/log_observer.hpp>

#include <tinyline/bus/clock.hpp>

namespace tinyline::bus {

namespace {

// Few observers, rarely changed: one shared lock per record. Held shared
// while they run, so removal waits for a call in progress.
struct Observers {
  std::shared_mutex mu;
  std::vector<std::pair<int, std::pair<const LogSink*, std::function<void(const LogRecord&)>>>> list;
  int next = 1;
};

Observers& observers() {
  static Observers o;
  return o;
}

void notify_observers(const LogSink* sink, const LogRecord& r) {
  auto& o = observers();
  std::shared_lock lk(o.mu);
  for (const auto& [id, entry] : o.list)
    if (entry.first == sink) entry.second(r);
}

}  // namespace

int add_log_observer(const LogSink* sink, std::function<void(const LogRecord&)> fn) {
  auto& o = observers();
  std::unique_lock lk(o.mu);
  const int id = o.next++;
  o.list.push_back({id, {sink, std::move(fn)}});
  return id;
}

void remove_log_observer(int id) {
  auto& o = observers();
  std::unique_lock lk(o.mu);
  std::erase_if(o.list, [id](const auto& e) { return e.first == id; });
}

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
  notify_observers(sink_.get(), r);
}

}  // namespace tinyline::bus
