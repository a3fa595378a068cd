// The graph across processes over DDS (loopback) beside the same graph in one
// process, in one run.
//
//   round trip:  ping -> relay -> pong, one message in flight; the time per
//                iteration is the round trip (p50/p99 as counters). The relay
//                runs in this process (InProcess) or in a second process that
//                this binary starts (`dds_bench --pong`), reached through the
//                DDS bridge on both sides (Dds).
//   stream:      the same path with up to 64 messages in flight: messages per
//                second through the round trip, and payload MB/s each way.
//   (DDS_BENCH_CONFIG=<xml> runs the DDS cases with another Cyclone configuration.)
//   with bridge: the in-process round trip with a bridge present and the
//                topics selected, but no remote reader: what DDS costs a
//                process that nobody outside listens to.
//
// Payload: sensor_msgs/PointCloud2 with `data` of the given size (2048 B is
// about one tiny-laser LaserScan; 1 MiB a dense cloud). Reliable QoS
// everywhere, so nothing is dropped and every iteration is complete.
#include <benchmark/benchmark.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <thread>

#include <fmt/format.h>

#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/node.hpp>
#include <tinyline/dds/bridge.hpp>
#include <tinyline/msg/sensor_msgs/point_cloud2.hpp>

using namespace tinyline;
using Cloud = sensor_msgs::msg::PointCloud2;
using SteadyClock = std::chrono::steady_clock;

namespace {

std::string g_self;  // this executable, for the pong process
constexpr std::size_t kWindow = 64;

/// `alone`: a tag nobody else uses (the bridge must find no remote reader).
dds::Settings settings(const std::string& process, bool alone = false) {
  dds::Settings s;
  const char* domain = std::getenv("DDS_BENCH_DOMAIN");  // the parent's, in the pong process
  s.domain_id = domain ? std::atoi(domain) : 1 + static_cast<int>(getpid() % 200);
  const char* parent = std::getenv("DDS_BENCH_TAG");
  s.config = dds::loopback_config(alone    ? fmt::format("bench_alone_{}", getpid())
                                  : parent ? parent
                                           : fmt::format("bench_{}", getpid()));
  // DDS_BENCH_CONFIG: measure another Cyclone configuration (tag it yourself).
  if (const char* c = std::getenv("DDS_BENCH_CONFIG"); c != nullptr && !alone) s.config = c;
  s.process_name = process;
  return s;
}

std::shared_ptr<bus::Context> quiet_context() {
  bus::ContextOptions o;
  o.log_sink = std::make_shared<bus::CaptureSink>();
  return bus::Context::create(o);
}

std::shared_ptr<bus::Node> make_node(const std::shared_ptr<bus::Context>& ctx, const std::string& name) {
  bus::NodeOptions o;
  o.name = name;
  o.context = ctx;
  return std::make_shared<bus::Node>(o);
}

/// ping -> pong, republishing the same object (zero copy in-process).
struct Relay {
  std::shared_ptr<bus::Node> node;
  std::shared_ptr<bus::GenericPublisher> pub;
  std::shared_ptr<bus::GenericSubscription> sub;
  Relay(const std::shared_ptr<bus::Context>& ctx, const std::string& name) {
    node = make_node(ctx, name);
    const auto& ts = msg::type_support<Cloud>();
    pub = node->create_generic_publisher("/bench/pong", ts, bus::QoS::reliable(kWindow * 4));
    sub = node->create_generic_subscription(
        "/bench/ping", ts, bus::QoS::reliable(kWindow * 4),
        [this](const std::shared_ptr<const void>& m, const msg::TypeSupport&, const bus::MessageInfo&) {
          pub->publish(m);
        });
  }
};

/// The second process: a bridge and a relay, until stdin closes (the
/// benchmark process went away) or SIGTERM.
int pong_main() {
  prctl(PR_SET_PDEATHSIG, SIGTERM);
  auto ctx = quiet_context();
  dds::BridgeOptions bo;
  bo.settings = settings("pong");
  bo.selection.all = true;
  auto bridge = dds::Bridge::create(ctx, bo);
  Relay relay(ctx, "relay");
  bus::MultiThreadedExecutor ex(ctx->clock(), 2);
  ex.add_node(bridge);
  ex.add_node(relay.node);
  bridge->start();
  std::thread spinner([&] { ex.spin(); });
  std::fputs("ready\n", stdout);
  std::fflush(stdout);
  char c;
  while (read(STDIN_FILENO, &c, 1) > 0) {
  }
  ex.stop();
  spinner.join();
  return 0;
}

/// Starts the pong process once; stops it at exit.
class PongProcess {
 public:
  static PongProcess& get() {
    static PongProcess p;
    return p;
  }
  ~PongProcess() {
    if (pid_ > 0) {
      close(stdin_);
      int st = 0;
      waitpid(pid_, &st, 0);
    }
  }

 private:
  PongProcess() {
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
      execl(g_self.c_str(), g_self.c_str(), "--pong", static_cast<char*>(nullptr));
      _exit(127);
    }
    close(in[0]);
    close(out[1]);
    stdin_ = in[1];
    char buf[6] = {0};
    if (read(out[0], buf, 6) != 6 || std::string(buf, 5) != "ready") throw std::runtime_error("pong process failed");
    close(out[0]);
  }
  pid_t pid_ = -1;
  int stdin_ = -1;
};

enum class Mode { InProcess, InProcessWithBridge, Dds };

/// The pinging side of one benchmark run.
struct Pinger {
  std::shared_ptr<bus::Context> ctx = quiet_context();
  std::shared_ptr<dds::Bridge> bridge;
  std::unique_ptr<Relay> relay;
  std::shared_ptr<bus::Node> node = make_node(ctx, "ping");
  std::shared_ptr<bus::Publisher<Cloud>> pub;
  std::shared_ptr<bus::Subscription<Cloud>> sub;
  std::atomic<std::uint64_t> pongs{0};
  std::unique_ptr<bus::MultiThreadedExecutor> ex;
  std::thread spinner;

  explicit Pinger(Mode mode) {
    pub = node->create_publisher<Cloud>("/bench/ping", bus::QoS::reliable(kWindow * 4));
    sub = node->create_subscription<Cloud>("/bench/pong", bus::QoS::reliable(kWindow * 4),
                                           [this](const Cloud&) { pongs.fetch_add(1, std::memory_order_release); });
    if (mode != Mode::Dds) relay = std::make_unique<Relay>(ctx, "relay");
    if (mode != Mode::InProcess) {
      if (mode == Mode::Dds) PongProcess::get();
      dds::BridgeOptions bo;
      bo.settings = settings("ping", mode == Mode::InProcessWithBridge);
      bo.selection.all = true;
      bridge = dds::Bridge::create(ctx, bo);
    }
    ex = std::make_unique<bus::MultiThreadedExecutor>(ctx->clock(), 2);
    ex->add_node(node);
    if (relay) ex->add_node(relay->node);
    if (bridge) {
      ex->add_node(bridge);
      bridge->start();
    }
    if (mode == Mode::Dds) {
      const auto r = bridge->wait_for_peers({{"/bench/ping", 1, 0}, {"/bench/pong", 0, 1}}, std::chrono::seconds(20));
      if (!r.ok) throw std::runtime_error("pong process not found: " + r.missing);
    }
    spinner = std::thread([this] { ex->spin(); });
  }
  ~Pinger() {
    ex->stop();
    spinner.join();
  }
  void wait_for(std::uint64_t n) {
    while (pongs.load(std::memory_order_acquire) < n) std::this_thread::yield();
  }
};

std::unique_ptr<Cloud> cloud(std::size_t bytes) {
  auto c = std::make_unique<Cloud>();
  c->header.frame_id = "bench";
  c->height = 1;
  c->width = static_cast<std::uint32_t>(bytes / 16);
  c->point_step = 16;
  c->data.resize(bytes, 0x5a);
  return c;
}

void round_trip(benchmark::State& state, Mode mode) {
  const auto bytes = static_cast<std::size_t>(state.range(0));
  Pinger p(mode);
  std::vector<double> rtt_us;
  std::uint64_t sent = 0;
  for (auto _ : state) {
    auto m = cloud(bytes);  // in the loop: a publisher makes a new message each time
    const auto t0 = SteadyClock::now();
    p.pub->publish(std::move(m));
    p.wait_for(++sent);
    rtt_us.push_back(std::chrono::duration<double, std::micro>(SteadyClock::now() - t0).count());
  }
  std::sort(rtt_us.begin(), rtt_us.end());
  state.counters["p50_us"] = rtt_us[rtt_us.size() / 2];
  state.counters["p99_us"] = rtt_us[rtt_us.size() * 99 / 100];
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * bytes));
}

void stream(benchmark::State& state, Mode mode) {
  const auto bytes = static_cast<std::size_t>(state.range(0));
  Pinger p(mode);
  std::uint64_t sent = 0;
  for (auto _ : state) {
    if (sent >= kWindow) p.wait_for(sent - kWindow + 1);
    p.pub->publish(cloud(bytes));
    ++sent;
  }
  p.wait_for(sent);  // every message made the round trip
  state.SetItemsProcessed(static_cast<std::int64_t>(sent));
  state.SetBytesProcessed(static_cast<std::int64_t>(sent * bytes));
}

void BM_InProcess_RoundTrip(benchmark::State& s) { round_trip(s, Mode::InProcess); }
void BM_InProcessWithBridge_RoundTrip(benchmark::State& s) { round_trip(s, Mode::InProcessWithBridge); }
void BM_Dds_RoundTrip(benchmark::State& s) { round_trip(s, Mode::Dds); }
void BM_InProcess_Stream(benchmark::State& s) { stream(s, Mode::InProcess); }
void BM_Dds_Stream(benchmark::State& s) { stream(s, Mode::Dds); }

void sizes(benchmark::internal::Benchmark* b) {
  for (long n : {64L, 2048L, 65536L, 1L << 20}) b->Arg(n);
  b->UseRealTime()->Unit(benchmark::kMicrosecond)->MinTime(1.0);
}

BENCHMARK(BM_InProcess_RoundTrip)->Apply(sizes);
BENCHMARK(BM_InProcessWithBridge_RoundTrip)->Apply(sizes);
BENCHMARK(BM_Dds_RoundTrip)->Apply(sizes);
BENCHMARK(BM_InProcess_Stream)->Apply(sizes);
BENCHMARK(BM_Dds_Stream)->Apply(sizes);

}  // namespace

int main(int argc, char** argv) {
  std::error_code ec;
  g_self = std::filesystem::read_symlink("/proc/self/exe", ec).string();
  if (argc > 1 && std::string(argv[1]) == "--pong") return pong_main();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
