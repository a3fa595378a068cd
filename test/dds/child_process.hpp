// SPDX-License-Identifier: Apache-2.0
// A child process for cross-process tests: its stdout and stderr merged into
// lines the test waits on (with deadlines, never sleeps), signals, and a
// destructor that leaves nothing running.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstring>
#include <functional>
#include <mutex>
#include <optional>
#include <regex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace tinyline::testing {

class ChildProcess {
 public:
  /// Starts argv[0] (a path) with argv; `env` entries ("NAME=value") are added
  /// to this process's environment.
  explicit ChildProcess(std::vector<std::string> argv, std::vector<std::string> env = {}) : argv_(std::move(argv)) {
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0) throw std::runtime_error("pipe failed");
    std::vector<char*> args;
    for (auto& a : argv_) args.push_back(a.data());
    args.push_back(nullptr);
    std::vector<std::string> envs;
    for (char** e = environ; *e != nullptr; ++e) envs.emplace_back(*e);
    for (auto& e : env) {
      const auto eq = e.find('=');
      std::erase_if(envs, [&](const std::string& x) { return x.compare(0, eq + 1, e, 0, eq + 1) == 0; });
      envs.push_back(e);
    }
    std::vector<char*> envp;
    for (auto& e : envs) envp.push_back(e.data());
    envp.push_back(nullptr);
    const pid_t parent = getpid();
    pid_ = fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {
      setpgid(0, 0);  // its own group: the test can signal it and everything it started
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (getppid() != parent) _exit(127);
      dup2(fds[1], STDOUT_FILENO);
      dup2(fds[1], STDERR_FILENO);
      execve(args[0], args.data(), envp.data());
      _exit(127);
    }
    close(fds[1]);
    fd_ = fds[0];
    reader_ = std::thread([this] { read_loop(); });
  }

  ~ChildProcess() {
    if (pid_ > 0 && !exited_) {
      kill(-pid_, SIGKILL);  // the whole group: a supervisor and its children
      waitpid(pid_, nullptr, 0);
    }
    if (reader_.joinable()) reader_.join();
    if (fd_ >= 0) close(fd_);
  }

  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }

  /// Waits until a line matches; returns it.
  std::optional<std::string> wait_for_line(const std::regex& re, std::chrono::milliseconds timeout,
                                           std::size_t from = 0) {
    std::optional<std::string> found;
    wait(
        [&] {
          for (std::size_t i = from; i < lines_.size(); ++i) {
            if (std::regex_search(lines_[i], re)) {
              found = lines_[i];
              return true;
            }
          }
          return false;
        },
        timeout);
    return found;
  }
  std::optional<std::string> wait_for_text(const std::string& needle, std::chrono::milliseconds timeout,
                                           std::size_t from = 0) {
    std::optional<std::string> found;
    wait(
        [&] {
          for (std::size_t i = from; i < lines_.size(); ++i) {
            if (lines_[i].find(needle) != std::string::npos) {
              found = lines_[i];
              return true;
            }
          }
          return false;
        },
        timeout);
    return found;
  }
  /// Waits until `n` lines contain `needle`; true if they did in time.
  bool wait_for_count(const std::string& needle, std::size_t n, std::chrono::milliseconds timeout) {
    bool ok = false;
    wait(
        [&] {
          std::size_t c = 0;
          for (const auto& l : lines_) c += l.find(needle) != std::string::npos ? 1 : 0;
          return ok = c >= n;
        },
        timeout);
    return ok;
  }
  /// Index of the first line containing `needle` at or after `from`, if any.
  std::optional<std::size_t> find(const std::string& needle, std::size_t from = 0) const {
    std::lock_guard lk(mu_);
    for (std::size_t i = from; i < lines_.size(); ++i)
      if (lines_[i].find(needle) != std::string::npos) return i;
    return std::nullopt;
  }

  std::vector<std::string> lines() const {
    std::lock_guard lk(mu_);
    return lines_;
  }
  std::string output() const {
    std::string s;
    for (const auto& l : lines()) s += l + "\n";
    return s;
  }

  void signal(int sig) { kill(pid_, sig); }

  /// Waits for the process to exit; returns its wait status.
  std::optional<int> wait_exit(std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      int st = 0;
      const pid_t r = waitpid(pid_, &st, WNOHANG);
      if (r == pid_) {
        exited_ = true;
        if (reader_.joinable()) reader_.join();  // its output is complete now
        return st;
      }
      if (std::chrono::steady_clock::now() >= deadline) return std::nullopt;
      // Woken by its output or after a short step: the exit itself signals nothing.
      std::unique_lock lk(mu_);
      cv_.wait_for(lk, std::chrono::milliseconds(10));
    }
  }

 private:
  void wait(const std::function<bool()>& pred, std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    std::unique_lock lk(mu_);
    cv_.wait_until(lk, deadline, [&] { return pred() || eof_; });  // after EOF nothing new comes
  }

  void read_loop() {
    std::string buf;
    char chunk[4096];
    for (;;) {
      const ssize_t n = read(fd_, chunk, sizeof(chunk));
      if (n <= 0) {
        if (n < 0 && errno == EINTR) continue;
        break;
      }
      buf.append(chunk, static_cast<std::size_t>(n));
      std::size_t start = 0;
      std::vector<std::string> fresh;
      for (std::size_t nl; (nl = buf.find('\n', start)) != std::string::npos; start = nl + 1) {
        fresh.push_back(buf.substr(start, nl - start));
      }
      buf.erase(0, start);
      if (!fresh.empty()) {
        std::lock_guard lk(mu_);
        lines_.insert(lines_.end(), fresh.begin(), fresh.end());
      }
      cv_.notify_all();
    }
    std::lock_guard lk(mu_);
    if (!buf.empty()) lines_.push_back(buf);
    eof_ = true;
    cv_.notify_all();
  }

  std::vector<std::string> argv_;
  pid_t pid_ = -1;
  int fd_ = -1;
  bool exited_ = false;
  std::thread reader_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::vector<std::string> lines_;
  bool eof_ = false;
};

}  // namespace tinyline::testing
