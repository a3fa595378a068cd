// SPDX-License-Identifier: Apache-2.0
// The ping-pong both DDS benchmarks run (dds_bench, dds_breakdown): a ping in
// this process, a relay in a second process this binary starts
// (`<binary> --pong bridge|engine`), two DDS hops per round trip.
//
//   Tinyline: ping node -> bridge -> DDS -> bridge -> relay node -> bridge ->
//             DDS -> bridge -> ping node's callback; nodes on executors, as a
//             user's graph runs.
//   Engine:   Cyclone DDS alone, as its own ddsperf ping/pong does it: the
//             same topics, sertype, QoS and configuration, but the relay is a
//             data-available listener on Cyclone's receive thread that writes
//             the bytes it took straight back (one copy), and the ping's
//             listener stamps the arrival. No executor, no (de)serialization.
//
// A round trip is stamped from just before the ping is published to the
// moment the pong reaches the ping side's callback (listener); the main
// thread then sleeps until told (futex), so its own wake-up is not counted.
// Payload: sensor_msgs/PointCloud2 with `data` of the given size.
#pragma once

#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <dds/dds.h>
#include <dds/ddsc/dds_loan_api.h>
#include <fmt/format.h>

#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/node.hpp>
#include <tinyline/dds/bridge.hpp>
#include <tinyline/dds/naming.hpp>
#include <tinyline/msg/sensor_msgs/point_cloud2.hpp>

#include "entities.hpp"
#include "probe.hpp"
#include "serdata.hpp"

namespace tinyline::bench_dds {

using Cloud = sensor_msgs::msg::PointCloud2;
using SteadyClock = std::chrono::steady_clock;

inline std::string g_self;           ///< this executable, for the pong process
constexpr std::size_t kWindow = 64;  ///< messages in flight in the stream benchmarks
constexpr std::size_t kDepth = kWindow * 4;

/// Every endpoint's QoS: keep-last deep enough that nothing in flight is
/// ever dropped (checked), which is KEEP_LAST 256 RELIABLE on DDS. A keep-all
/// writer could block Cyclone's receive thread in the engine's relay, which
/// writes from there (ddsperf's pong writers are keep-last for that reason).
inline bus::QoS bench_qos() { return bus::QoS::keep_last(kDepth); }

inline std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(SteadyClock::now().time_since_epoch()).count();
}

/// Both processes' DDS settings: a loopback configuration tagged for this
/// run, on a domain of its own (`alone`: a tag nobody else has, so the bridge
/// finds no remote reader). DDS_BENCH_CONFIG=<xml> measures another Cyclone
/// configuration (tag it yourself).
inline dds::Settings settings(const std::string& process, bool alone = false) {
  dds::Settings s;
  const char* domain = std::getenv("DDS_BENCH_DOMAIN");  // the parent's, in the pong process
  s.domain_id = domain ? std::atoi(domain) : 1 + static_cast<int>(getpid() % 200);
  const char* parent = std::getenv("DDS_BENCH_TAG");
  s.config = dds::loopback_config(alone    ? fmt::format("bench_alone_{}", getpid())
                                  : parent ? parent
                                           : fmt::format("bench_{}", getpid()));
  if (const char* c = std::getenv("DDS_BENCH_CONFIG"); c != nullptr && !alone) s.config = c;
  // DDS_BENCH_SHM=1: Cyclone's shared memory (a RouDi must run), both processes.
  if (const char* shm = std::getenv("DDS_BENCH_SHM"); shm != nullptr && !alone) s.shared_memory = *shm == '1';
  s.process_name = process;
  return s;
}

/// The executors' polling time (ExecutorOptions::spin); DDS_BENCH_SPIN_US
/// measures another.
inline bus::Duration executor_spin() {
  const char* us = std::getenv("DDS_BENCH_SPIN_US");
  return us ? std::chrono::microseconds(std::atoi(us)) : bus::ExecutorOptions{}.spin;
}

inline std::shared_ptr<bus::Context> quiet_context() {
  bus::ContextOptions o;
  o.log_sink = std::make_shared<bus::CaptureSink>();
  return bus::Context::create(o);
}

inline std::shared_ptr<bus::Node> make_node(const std::shared_ptr<bus::Context>& ctx, const std::string& name) {
  bus::NodeOptions o;
  o.name = name;
  o.context = ctx;
  return std::make_shared<bus::Node>(o);
}

inline std::unique_ptr<Cloud> cloud(std::size_t bytes) {
  auto c = std::make_unique<Cloud>();
  c->header.frame_id = "bench";
  c->height = 1;
  c->width = static_cast<std::uint32_t>(bytes / 16);
  c->point_step = 16;
  c->data.resize(bytes, 0x5a);
  return c;
}

/// ping -> pong, republishing the same object (zero copy in-process).
struct Relay {
  std::shared_ptr<bus::Node> node;
  std::shared_ptr<bus::GenericPublisher> pub;
  std::shared_ptr<bus::GenericSubscription> sub;
  Relay(const std::shared_ptr<bus::Context>& ctx, const std::string& name) {
    node = make_node(ctx, name);
    const auto& ts = msg::type_support<Cloud>();
    pub = node->create_generic_publisher("/bench/pong", ts, bench_qos());
    sub = node->create_generic_subscription(
        "/bench/ping", ts, bench_qos(),
        [this](const std::shared_ptr<const void>& m, const msg::TypeSupport&, const bus::MessageInfo&) {
          TL_DDS_PROBE(Arrival);
          TL_DDS_PROBE(Publish);
          pub->publish(m);
        });
  }
};

/// What the ping side counts: pongs arrived, and when the last one did.
struct Arrivals {
  std::atomic<std::uint64_t> count{0};
  std::atomic<std::int64_t> last_ns{0};

  void arrived() {
    TL_DDS_PROBE(Arrival);
    last_ns.store(now_ns(), std::memory_order_relaxed);
    count.fetch_add(1, std::memory_order_release);
    count.notify_one();
  }
  /// Sleeps until `n` pongs arrived.
  void wait_for(std::uint64_t n) {
    for (std::uint64_t c = count.load(std::memory_order_acquire); c < n; c = count.load(std::memory_order_acquire)) {
      count.wait(c, std::memory_order_acquire);
    }
  }
};

// ---------------------------------------------------------------------------- the engine alone

namespace engine {

inline dds::EndpointQos endpoint_qos(bool reader, bool shared_memory) {
  const std::vector<bus::QoS> q{bench_qos()};
  dds::EndpointQos e = reader ? dds::requested_qos(q) : dds::offered_qos(q);
  e.accept_local = shared_memory;  // shared memory's condition; no writer of its own on the topic
  return e;
}

inline dds_entity_t writer(dds::Participant& p, const dds::detail::TopicHandle& t) {
  dds::detail::Qos q;
  dds::detail::fill_qos(q, endpoint_qos(false, p.shared_memory()), false, p.identity(), &msg::type_support<Cloud>());
  const dds_entity_t w = dds_create_writer(p.handle(), t.topic, q.q, nullptr);
  if (w < 0) throw std::runtime_error("engine: cannot create a writer");
  return w;
}

inline dds_entity_t reader(dds::Participant& p, const dds::detail::TopicHandle& t, dds_on_data_available_fn fn,
                           void* arg) {
  dds::detail::Qos q;
  dds::detail::fill_qos(q, endpoint_qos(true, p.shared_memory()), true, p.identity(), &msg::type_support<Cloud>());
  dds_listener_t* l = dds_create_listener(arg);
  dds_lset_data_available(l, fn);
  const dds_entity_t r = dds_create_reader(p.handle(), t.topic, q.q, l);
  dds_delete_listener(l);
  if (r < 0) throw std::runtime_error("engine: cannot create a reader");
  return r;
}

inline dds::detail::TopicHandle topic(dds::Participant& p, const std::string& name) {
  const auto& ts = msg::type_support<Cloud>();
  return dds::detail::create_topic(p.handle(), dds::dds_topic_name(name), std::string(ts.dds_type_name()), &ts,
                                   p.settings().max_sample_bytes);
}

/// Writes a copy of `bytes` (what a writer of serialized data must do: the
/// caller keeps its buffer), through a shared-memory chunk when the writer
/// can use one, as the bridge does.
inline void write_copy(dds_entity_t w, const ddsi_sertype* type, std::span<const std::uint8_t> bytes) {
  TL_DDS_PROBE(Publish);
  std::string why;
  ddsi_serdata* sd = dds::detail::make_serdata_for(w, dds_is_shared_memory_available(w), type,
                                                   std::vector<std::uint8_t>(bytes.begin(), bytes.end()), why);
  if (sd == nullptr) throw std::runtime_error("engine: " + why);
  const dds_return_t rc = dds_writecdr(w, sd);
  TL_DDS_PROBE(Written);
  if (rc < 0)
    throw std::runtime_error(
        fmt::format("engine: write failed in {} (parent {}): {}", getpid(), getppid(), dds_strretcode(rc)));
}

/// Takes every sample of `r`, calling fn(bytes) for each.
template <class F>
void take_all(dds_entity_t r, F&& fn) {
  ddsi_serdata* sd = nullptr;
  dds_sample_info_t info;
  while (dds_takecdr(r, &sd, 1, &info, DDS_ANY_STATE) > 0) {
    if (info.valid_data) fn(dds::detail::serdata_bytes(sd));
    ddsi_serdata_unref(sd);
  }
}

/// True once each endpoint matched exactly one remote one, the pong process
/// (and no longer one that went away), or false when the timeout passed.
inline bool wait_matched(dds_entity_t w, dds_entity_t r, std::chrono::seconds timeout) {
  const auto deadline = SteadyClock::now() + timeout;
  while (SteadyClock::now() < deadline) {
    dds_publication_matched_status_t ws{};
    dds_subscription_matched_status_t rs{};
    dds_get_publication_matched_status(w, &ws);
    dds_get_subscription_matched_status(r, &rs);
    if (ws.current_count == 1 && rs.current_count == 1) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));  // discovery, before any measurement
  }
  return false;
}

}  // namespace engine

/// The engine's relay: pings in, the same bytes out, on Cyclone's receive thread.
struct EnginePong {
  dds::Participant participant{settings("pong")};
  dds::detail::TopicHandle ping = engine::topic(participant, "/bench/ping");
  dds::detail::TopicHandle pong = engine::topic(participant, "/bench/pong");
  dds_entity_t writer = engine::writer(participant, pong);
  dds_entity_t reader = engine::reader(participant, ping, &EnginePong::on_ping, this);

  static void on_ping(dds_entity_t r, void* arg) {
    auto* self = static_cast<EnginePong*>(arg);
    engine::take_all(r, [&](std::span<const std::uint8_t> b) {
      TL_DDS_PROBE(Arrival);
      engine::write_copy(self->writer, self->pong.sertype, b);
    });
  }
};

/// The engine's ping side.
struct EnginePinger {
  Arrivals arrivals;
  dds::Participant participant{settings("ping")};
  dds::detail::TopicHandle ping_topic = engine::topic(participant, "/bench/ping");
  dds::detail::TopicHandle pong_topic = engine::topic(participant, "/bench/pong");
  dds_entity_t writer = engine::writer(participant, ping_topic);
  dds_entity_t reader = engine::reader(participant, pong_topic, &EnginePinger::on_pong, this);
  std::vector<std::uint8_t> bytes;

  EnginePinger() {
    if (!engine::wait_matched(writer, reader, std::chrono::seconds(20))) {
      throw std::runtime_error("engine pong process not found");
    }
  }
  ~EnginePinger() { dds_delete(reader); }  // no listener may run on a half-destroyed pinger
  void set_payload(std::size_t payload) {
    bytes.clear();
    msg::type_support<Cloud>().serialize(cloud(payload).get(), bytes);
  }
  void ping() { engine::write_copy(writer, ping_topic.sertype, bytes); }

  static void on_pong(dds_entity_t r, void* arg) {
    auto* self = static_cast<EnginePinger*>(arg);
    engine::take_all(r, [&](std::span<const std::uint8_t>) { self->arrivals.arrived(); });
  }
};

// ---------------------------------------------------------------------------- the pong process

enum class PongKind { Bridge, Engine };

/// The second process: a bridge and a relay on an executor (or the engine's
/// relay) until stdin closes (the benchmark process went away) or SIGTERM.
inline int pong_main(PongKind kind) {
  prctl(PR_SET_PDEATHSIG, SIGTERM);
  std::shared_ptr<bus::Context> ctx;
  std::shared_ptr<dds::Bridge> bridge;
  std::unique_ptr<Relay> relay;
  std::unique_ptr<bus::MultiThreadedExecutor> ex;
  std::unique_ptr<EnginePong> engine_pong;
  std::thread spinner;
  if (kind == PongKind::Bridge) {
    ctx = quiet_context();
    dds::BridgeOptions bo;
    bo.settings = settings("pong");
    bo.selection.all = true;
    bridge = dds::Bridge::create(ctx, bo);
    relay = std::make_unique<Relay>(ctx, "relay");
    ex = std::make_unique<bus::MultiThreadedExecutor>(ctx->clock(), 2, executor_spin());
    ex->add_node(bridge);
    ex->add_node(relay->node);
    bridge->start();
    spinner = std::thread([&] { ex->spin(); });
  } else {
    engine_pong = std::make_unique<EnginePong>();
  }
  std::fputs("ready\n", stdout);
  std::fflush(stdout);
  char c;
  while (read(STDIN_FILENO, &c, 1) > 0) {}
  if (ex) {
    ex->stop();
    spinner.join();
  }
#if defined(TINYLINE_DDS_PROBES)
  if (const char* out = std::getenv("DDS_PROBE_OUT")) dds::probe::write(out);
#endif
  return 0;
}

/// A pong process; it ends when this goes (its stdin closes).
class PongProcess {
 public:
  explicit PongProcess(PongKind kind) : kind_(kind) { start(); }
  PongKind kind() const { return kind_; }
  pid_t pid() const { return pid_; }
  ~PongProcess() {
    close(stdin_);
    int st = 0;
    waitpid(pid_, &st, 0);
  }

 private:
  void start() {
    int in[2], out[2];
    if (pipe(in) != 0 || pipe(out) != 0) throw std::runtime_error("pipe");
    const std::string tag = fmt::format("bench_{}", getpid());
    setenv("DDS_BENCH_TAG", tag.c_str(), 1);
    setenv("DDS_BENCH_DOMAIN", std::to_string(settings("ping").domain_id).c_str(), 1);
    pid_ = fork();
    if (pid_ == 0) {
      dup2(in[0], STDIN_FILENO);
      dup2(out[1], STDOUT_FILENO);
      close(in[1]);
      close(out[0]);
      execl(g_self.c_str(), g_self.c_str(), "--pong", kind_ == PongKind::Bridge ? "bridge" : "engine",
            static_cast<char*>(nullptr));
      _exit(127);
    }
    close(in[0]);
    close(out[1]);
    stdin_ = in[1];
    char buf[6] = {0};
    if (read(out[0], buf, 6) != 6 || std::string(buf, 5) != "ready") throw std::runtime_error("pong process failed");
    close(out[0]);
  }
  PongKind kind_;
  pid_t pid_ = -1;
  int stdin_ = -1;
};

/// `<binary> --pong bridge|engine` runs the pong process; returns -1 otherwise.
inline int maybe_pong_main(int argc, char** argv) {
  std::error_code ec;
  g_self = std::filesystem::read_symlink("/proc/self/exe", ec).string();
  if (argc < 3 || std::string(argv[1]) != "--pong") return -1;
  return pong_main(std::string(argv[2]) == "engine" ? PongKind::Engine : PongKind::Bridge);
}

// ---------------------------------------------------------------------------- tinyline's ping side

enum class Mode { InProcess, InProcessWithBridge, Dds };

/// The pinging side: a node publishing pings and counting pongs, with the
/// relay in this process or (Dds) behind the bridge in the pong process.
struct Pinger {
  Arrivals arrivals;
  std::shared_ptr<bus::Context> ctx = quiet_context();
  std::shared_ptr<dds::Bridge> bridge;
  std::unique_ptr<Relay> relay;
  std::shared_ptr<bus::Node> node = make_node(ctx, "ping");
  std::shared_ptr<bus::Publisher<Cloud>> pub;
  std::shared_ptr<bus::Subscription<Cloud>> sub;
  std::unique_ptr<bus::MultiThreadedExecutor> ex;
  std::thread spinner;

  explicit Pinger(Mode mode) {
    pub = node->create_publisher<Cloud>("/bench/ping", bench_qos());
    sub = node->create_subscription<Cloud>("/bench/pong", bench_qos(), [this](const Cloud&) { arrivals.arrived(); });
    if (mode != Mode::Dds) relay = std::make_unique<Relay>(ctx, "relay");
    if (mode != Mode::InProcess) {
      dds::BridgeOptions bo;
      bo.settings = settings("ping", mode == Mode::InProcessWithBridge);
      bo.selection.all = true;
      bridge = dds::Bridge::create(ctx, bo);
    }
    ex = std::make_unique<bus::MultiThreadedExecutor>(ctx->clock(), 2, executor_spin());
    ex->add_node(node);
    if (relay) ex->add_node(relay->node);
    if (bridge) {
      ex->add_node(bridge);
      bridge->start();
    }
    if (mode == Mode::Dds) wait_for_pong();
    spinner = std::thread([this] { ex->spin(); });
  }
  ~Pinger() {
    ex->stop();
    spinner.join();
  }

 private:
  /// Exactly the pong process's endpoints matched (not one that went away).
  void wait_for_pong() {
    const auto deadline = SteadyClock::now() + std::chrono::seconds(20);
    while (SteadyClock::now() < deadline) {
      std::size_t readers = 0, writers = 0;
      for (const auto& l : bridge->stats()) {
        if (l.topic == "/bench/ping") readers = l.remote_readers;
        if (l.topic == "/bench/pong") writers = l.remote_writers;
      }
      if (readers == 1 && writers == 1) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));  // discovery, before any measurement
    }
    throw std::runtime_error("the pong process was not found");
  }
};

/// The ping side of the cross-process cases and their pong process, kept
/// across benchmark runs: a participant that goes away stays matched on the
/// other side until its lease ends, and a reliable writer would keep data
/// for it. Switching between the engine and tinyline restarts the pong.
class Sessions {
 public:
  static Sessions& get() {
    static Sessions s;
    return s;
  }
  EnginePinger& engine() {
    if (!engine_) {
      use(PongKind::Engine);
      engine_ = std::make_unique<EnginePinger>();
    }
    return *engine_;
  }
  Pinger& tinyline() {
    if (!tinyline_) {
      use(PongKind::Bridge);
      tinyline_ = std::make_unique<Pinger>(Mode::Dds);
    }
    return *tinyline_;
  }
  /// The pong process running now, or -1.
  pid_t pong_pid() const { return pong_ ? pong_->pid() : -1; }
  /// Ends the ping sides, then the pong process.
  void close() {
    engine_.reset();
    tinyline_.reset();
    pong_.reset();
  }

 private:
  void use(PongKind kind) {
    if (pong_ && pong_->kind() == kind) return;
    close();
    pong_ = std::make_unique<PongProcess>(kind);
  }
  std::unique_ptr<PongProcess> pong_;
  std::unique_ptr<EnginePinger> engine_;
  std::unique_ptr<Pinger> tinyline_;
};

}  // namespace tinyline::bench_dds
