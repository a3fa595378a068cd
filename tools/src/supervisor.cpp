// SPDX-License-Identifier: Apache-2.0
#include "supervisor.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include <fmt/format.h>

namespace tinyline::tools {

using SteadyClock = std::chrono::steady_clock;

struct Supervisor::Child {
  ChildSpec spec;
  pid_t pid = -1;
  int out = -1, err = -1;  // read ends of its stdout / stderr pipes
  int gate = -1;           // write end of its stdin while it waits at the start gate
  bool ready = false;      // it printed kReadyLine
  std::string out_buf, err_buf;
  bool stop_requested = false;
  std::optional<SteadyClock::time_point> restart_at;
  int starts = 0;
};

std::string describe_exit(int st) {
  if (WIFEXITED(st)) return fmt::format("exited with code {}", WEXITSTATUS(st));
  if (WIFSIGNALED(st)) return fmt::format("was killed by signal {} ({})", WTERMSIG(st), strsignal(WTERMSIG(st)));
  return "stopped";
}

Supervisor::Supervisor(SupervisorOptions options) : options_(options) {
  // A gate write to a child that just died must fail with EPIPE, not kill us.
  signal(SIGPIPE, SIG_IGN);
}

Supervisor::~Supervisor() { stop_all(); }

void Supervisor::start(ChildSpec spec) {
  auto c = std::make_unique<Child>();
  c->spec = std::move(spec);
  spawn(*c);
  children_.push_back(std::move(c));
}

void Supervisor::spawn(Child& c) {
  int out[2], err[2];
  if (pipe2(out, O_CLOEXEC) != 0) throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  if (pipe2(err, O_CLOEXEC) != 0) {
    close(out[0]);
    close(out[1]);
    throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  }
  // Everything the child needs is prepared before fork: between fork and exec
  // only async-signal-safe calls (the executor's threads may hold locks).
  int gate[2] = {-1, -1};
  if (c.spec.gated && pipe2(gate, O_CLOEXEC) != 0) {
    for (int fd : {out[0], out[1], err[0], err[1]}) close(fd);
    throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  }
  std::vector<std::string> args = c.spec.argv;
  if (c.starts > 0) args.insert(args.end(), c.spec.restart_args.begin(), c.spec.restart_args.end());
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) {
    for (int fd : {out[0], out[1], err[0], err[1], gate[0], gate[1]})
      if (fd >= 0) close(fd);
    throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
  }
  if (pid == 0) {
    setpgid(0, 0);
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent) _exit(127);  // the supervisor died before prctl
    dup2(out[1], STDOUT_FILENO);
    dup2(err[1], STDERR_FILENO);
    if (gate[0] >= 0) dup2(gate[0], STDIN_FILENO);
    signal(SIGINT, SIG_DFL);
    signal(SIGPIPE, SIG_DFL);
    signal(SIGTERM, SIG_DFL);
    execv(argv[0], argv.data());
    const char msg[] = "exec failed\n";
    (void)!write(STDERR_FILENO, msg, sizeof(msg) - 1);
    _exit(127);
  }
  close(out[1]);
  close(err[1]);
  if (gate[0] >= 0) close(gate[0]);
  c.gate = gate[1];
  c.ready = false;
  if (gates_open_ && c.gate >= 0) {  // a restart into a running graph: no one to wait for
    (void)!write(c.gate, "go\n", 3);
    close(c.gate);
    c.gate = -1;
  }
  fcntl(out[0], F_SETFL, O_NONBLOCK);
  fcntl(err[0], F_SETFL, O_NONBLOCK);
  c.pid = pid;
  c.out = out[0];
  c.err = err[0];
  c.stop_requested = false;
  c.restart_at.reset();
  ++c.starts;
  std::string nodes;
  for (const auto& n : c.spec.nodes) nodes += (nodes.empty() ? "" : ", ") + n;
  fmt::print(options_.err, "[launch] {} process '{}' (pid {}): {}\n", c.starts == 1 ? "started" : "restarted",
             c.spec.name, pid, nodes);
  std::fflush(options_.err);
}

void Supervisor::forward(Child& c, int& fd, bool drain) {
  const bool is_out = &fd == &c.out;
  std::string& buf = is_out ? c.out_buf : c.err_buf;
  std::FILE* to = is_out ? options_.out : options_.err;
  char chunk[4096];
  bool eof = drain;
  for (;;) {
    const ssize_t n = read(fd, chunk, sizeof(chunk));
    if (n > 0) {
      buf.append(chunk, static_cast<std::size_t>(n));
      continue;
    }
    if (n == 0 || (errno != EAGAIN && errno != EINTR)) eof = true;
    break;  // EAGAIN: nothing more for now
  }
  std::size_t start = 0;
  std::string lines;
  for (std::size_t nl; (nl = buf.find('\n', start)) != std::string::npos; start = nl + 1) {
    const std::string_view line = std::string_view(buf).substr(start, nl - start);
    if (is_out && line == kReadyLine) {
      c.ready = true;
      continue;
    }
    lines += fmt::format("[{}] {}\n", c.spec.name, line);
  }
  buf.erase(0, start);
  if (eof && !buf.empty()) {
    lines += fmt::format("[{}] {}\n", c.spec.name, buf);
    buf.clear();
  }
  if (!lines.empty()) {
    std::fwrite(lines.data(), 1, lines.size(), to);
    std::fflush(to);
  }
  if (eof) {  // the child closed it (or exited): stop polling it
    close(fd);
    fd = -1;
  }
}

void Supervisor::poll(std::chrono::milliseconds budget) {
  std::vector<pollfd> fds;
  std::vector<int*> owners_fd;
  std::vector<Child*> owners;
  for (auto& c : children_) {
    for (int* fd : {&c->out, &c->err}) {
      if (*fd >= 0) {
        fds.push_back(pollfd{*fd, POLLIN, 0});
        owners.push_back(c.get());
        owners_fd.push_back(fd);
      }
    }
  }
  // Sleep no longer than the next restart is due.
  auto wait = budget;
  for (auto& c : children_) {
    if (c->restart_at) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(*c->restart_at - SteadyClock::now());
      wait = std::max(std::chrono::milliseconds(0), std::min(wait, left));
    }
  }
  if (!fds.empty()) {
    const int n = ::poll(fds.data(), fds.size(), static_cast<int>(wait.count()));
    if (n > 0) {
      for (std::size_t i = 0; i < fds.size(); ++i) {
        if (fds[i].revents != 0) forward(*owners[i], *owners_fd[i], false);
      }
    }
  } else if (wait.count() > 0) {
    ::poll(nullptr, 0, static_cast<int>(wait.count()));
  }
  reap(false);
  for (auto& c : children_) {
    if (c->restart_at && SteadyClock::now() >= *c->restart_at) {
      try {
        spawn(*c);
      } catch (const std::exception& e) {
        fmt::print(options_.err, "[launch] cannot restart process '{}': {}\n", c->spec.name, e.what());
        c->restart_at.reset();
      }
    }
  }
}

void Supervisor::reap(bool stopping) {
  for (auto& c : children_) {
    if (c->pid <= 0) continue;
    int st = 0;
    const pid_t r = waitpid(c->pid, &st, WNOHANG);
    if (r != c->pid) continue;
    // Its pipes hold its last words (a crash message): forward them all.
    for (int* fd : {&c->out, &c->err})
      if (*fd >= 0) forward(*c, *fd, true);
    const pid_t pid = c->pid;
    c->pid = -1;
    if (c->gate >= 0) {
      close(c->gate);
      c->gate = -1;
    }
    const bool clean = WIFEXITED(st) && WEXITSTATUS(st) == 0;
    if (c->stop_requested || stopping) {
      if (!clean && !(WIFSIGNALED(st) && (WTERMSIG(st) == SIGINT || WTERMSIG(st) == SIGKILL))) {
        fmt::print(options_.err, "[launch] process '{}' (pid {}) {} while stopping\n", c->spec.name, pid,
                   describe_exit(st));
      }
      continue;
    }
    ++failures_;
    std::string nodes;
    for (const auto& n : c->spec.nodes) nodes += (nodes.empty() ? "" : ", ") + n;
    if (c->spec.respawn) {
      fmt::print(options_.err, "[launch] process '{}' (pid {}; nodes {}) {}; restarting in {:.1f} s\n", c->spec.name,
                 pid, nodes, describe_exit(st), options_.respawn_delay_s);
      c->restart_at = SteadyClock::now() + std::chrono::duration_cast<SteadyClock::duration>(
                                               std::chrono::duration<double>(options_.respawn_delay_s));
    } else {
      fmt::print(options_.err, "[launch] process '{}' (pid {}; nodes {}) {}; the others keep running\n", c->spec.name,
                 pid, nodes, describe_exit(st));
    }
    std::fflush(options_.err);
  }
}

void Supervisor::stop_all() {
  for (auto& c : children_) {
    c->restart_at.reset();
    if (c->pid > 0) {
      c->stop_requested = true;
      kill(c->pid, SIGINT);
    }
  }
  const auto deadline = SteadyClock::now() + std::chrono::duration_cast<SteadyClock::duration>(
                                                 std::chrono::duration<double>(options_.grace_s));
  while (running() > 0 && SteadyClock::now() < deadline) poll(std::chrono::milliseconds(20));
  for (auto& c : children_) {
    if (c->pid > 0) {
      fmt::print(options_.err, "[launch] process '{}' (pid {}) did not stop within {:.1f} s; killing it\n",
                 c->spec.name, c->pid, options_.grace_s);
      kill(c->pid, SIGKILL);
      int st = 0;
      waitpid(c->pid, &st, 0);
      for (int* fd : {&c->out, &c->err})
        if (*fd >= 0) forward(*c, *fd, true);
      c->pid = -1;
    }
  }
  reap(true);
}

bool Supervisor::all_ready() const { return not_ready().empty(); }

std::vector<std::string> Supervisor::not_ready() const {
  std::vector<std::string> out;
  for (const auto& c : children_)
    if (c->spec.gated && c->pid > 0 && !c->ready) out.push_back(c->spec.name);
  return out;
}

void Supervisor::open_gates() {
  gates_open_ = true;
  for (auto& c : children_) {
    if (c->gate < 0) continue;
    (void)!write(c->gate, "go\n", 3);  // EPIPE if it just died: reap() reports that
    close(c->gate);
    c->gate = -1;
  }
}

std::size_t Supervisor::running() const {
  std::size_t n = 0;
  for (const auto& c : children_) n += c->pid > 0 ? 1 : 0;
  return n;
}

pid_t Supervisor::pid_of(const std::string& name) const {
  for (const auto& c : children_)
    if (c->spec.name == name) return c->pid;
  return -1;
}

}  // namespace tinyline::tools
