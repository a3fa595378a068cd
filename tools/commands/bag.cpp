// tinyline bag record|play|info|echo|recover: MCAP bags from the command line.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <thread>

#include <fmt/format.h>

#include <tinyline/bag/player.hpp>
#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/recorder.hpp>
#include <tinyline/bag/recover.hpp>
#include <tinyline/bag/ros2.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/launch/launch.hpp>
#include <tinyline/msg/yaml_writer.hpp>
#include <tinyline/tools/command.hpp>

#include "../src/args.hpp"

namespace tinyline::tools {
namespace {

constexpr const char* kHelp = R"(usage: tinyline bag <command> ...

  record [-o FILE] [TOPIC ...] [options]   record topics (all by default) to an MCAP bag
  play FILE [options]                      publish a bag's messages on their topics
  info FILE [--verify]                     topics, types, counts, duration, compression
  echo FILE TOPIC [--limit N] [--full]     print a topic's messages as YAML
  recover IN OUT [--compression C]         rewrite a damaged or unfinished bag as a complete one

record options:
  -o FILE            output file (default tinyline_<date>_<time>.mcap)
  --launch FILE      run this launch file in the same process and record its topics
                     (further name:=value arguments go to the launch file)
  --exclude TOPIC    do not record TOPIC (repeatable)
  --compression C    none, lz4 (default) or zstd
  --chunk-size KB    uncompressed chunk size [KiB] (default 1024)
  --duration S       stop after S seconds (default: Ctrl-C)
play options:
  --rate R           playback speed, x real time (default 1; 0 = as fast as possible)
  --loop             start over at the end
  --topics T [T...]  play only these topics
  --start S          skip the first S seconds of the bag
  --clock            publish /clock (rosgraph_msgs/Clock) and drive sim time
  --clock-hz H       /clock rate between messages (default 100)
  --duration S       stop after S seconds of playing (default: the bag's end, or Ctrl-C with --loop)

`bag record` records the topics of its own process: those of --launch, and
those a transport bridges in. To record inside a running launch file, add a
node {pkg: bag, exec: recorder} to it (parameters: tinyline describe bag/recorder).
)";

std::atomic<int> g_signal{0};
extern "C" void tinyline_bag_cli_on_signal(int sig) { g_signal.store(sig); }

struct SignalScope {
  SignalScope() {
    g_signal.store(0);
    std::signal(SIGINT, tinyline_bag_cli_on_signal);
    std::signal(SIGTERM, tinyline_bag_cli_on_signal);
  }
  ~SignalScope() {
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
  }
};

// Progress on a terminal: one line, redrawn in place on stderr.
void progress(const std::string& line) {
  if (!isatty(STDERR_FILENO)) return;
  fmt::print(stderr, "\r\033[K{}", line);
  std::fflush(stderr);
}
void progress_done() {
  if (isatty(STDERR_FILENO)) fmt::print(stderr, "\n");
}

std::string human_bytes(std::uint64_t b) {
  if (b >= (1ULL << 30)) return fmt::format("{:.2f} GiB", static_cast<double>(b) / (1ULL << 30));
  if (b >= (1ULL << 20)) return fmt::format("{:.2f} MiB", static_cast<double>(b) / (1ULL << 20));
  if (b >= (1ULL << 10)) return fmt::format("{:.1f} KiB", static_cast<double>(b) / (1ULL << 10));
  return fmt::format("{} B", b);
}

// Unix times read as dates; sim times (small) as seconds.
std::string human_time(bag::Timestamp t) {
  const double s = static_cast<double>(t) * 1e-9;
  if (s < 1e8) return fmt::format("{:.3f} s", s);
  const std::time_t secs = static_cast<std::time_t>(t / 1'000'000'000ULL);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%d %H:%M:%S", &tm);
  return fmt::format("{}.{:03d} UTC ({:.3f})", buf, static_cast<int>((t / 1'000'000ULL) % 1000), s);
}

// Options that take several values (`--topics a b c`) are cut out before Args sees the rest.
std::vector<std::string> take_list(std::vector<std::string>& argv, const std::string& opt) {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < argv.size();) {
    if (argv[i] != opt) {
      ++i;
      continue;
    }
    std::size_t j = i + 1;
    while (j < argv.size() && argv[j].rfind("--", 0) != 0) {
      std::string v = argv[j];
      std::size_t start = 0;
      while (start <= v.size()) {  // also "a,b"
        const std::size_t comma = v.find(',', start);
        const std::string part = v.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
        if (!part.empty()) out.push_back(part);
        if (comma == std::string::npos) break;
        start = comma + 1;
      }
      ++j;
    }
    if (j == i + 1) throw UsageError(opt + " needs at least one value");
    argv.erase(argv.begin() + static_cast<std::ptrdiff_t>(i), argv.begin() + static_cast<std::ptrdiff_t>(j));
  }
  return out;
}

// ---------------------------------------------------------------------------- info

int cmd_info(const std::vector<std::string>& argv) {
  Args a(argv, {}, {"--verify", "--help", "-h"});
  if (a.positional().size() != 1) throw UsageError("expected FILE (tinyline bag --help)");
  const std::string path = a.positional()[0];
  bag::Reader r;
  if (bag::Status s = r.open(path); !s.ok()) {
    fmt::print(stderr, "{}\n", s.str());
    return 1;
  }
  bag::Status problem;
  if (!r.has_summary()) problem = r.scan();
  const auto& sum = r.summary();
  const auto& st = sum.statistics;
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  fmt::print("file:         {} ({}, {}, {})\n", path, human_bytes(ec ? 0 : size),
             r.complete() ? "complete" : "NOT complete: no footer", r.has_summary() ? "indexed" : "no summary, scanned");
  fmt::print("profile:      {} (written by {})\n", sum.header.profile.empty() ? "(none)" : sum.header.profile,
             sum.header.library);
  if (st.message_count > 0) {
    fmt::print("start:        {}\nend:          {}\nduration:     {:.3f} s\n", human_time(st.message_start_time),
               human_time(st.message_end_time),
               static_cast<double>(st.message_end_time - st.message_start_time) * 1e-9);
  }
  fmt::print("messages:     {}\n", st.message_count);
  std::string comp;
  for (const auto& [c, n] : sum.chunks_by_compression) {
    comp += fmt::format("{}{}: {}", comp.empty() ? "" : ", ", c.empty() ? "none" : c, n);
  }
  std::uint64_t raw = 0, packed = 0;
  for (const auto& ci : sum.chunk_indexes) {
    raw += ci.uncompressed_size;
    packed += ci.compressed_size;
  }
  fmt::print("chunks:       {}{}{}\n", st.chunk_count, comp.empty() ? "" : " (" + comp + ")",
             packed > 0 ? fmt::format(", {} -> {} ({:.2f}x)", human_bytes(raw), human_bytes(packed),
                                      static_cast<double>(raw) / static_cast<double>(packed))
                        : std::string());
  fmt::print("attachments:  {}\nmetadata:     {}\n", st.attachment_count, st.metadata_count);
  const double dur = static_cast<double>(st.message_end_time - st.message_start_time) * 1e-9;
  std::size_t w_topic = 5, w_type = 4;
  for (const auto& [id, ch] : r.channels()) {
    w_topic = std::max(w_topic, ch.topic.size());
    auto sc = r.schemas().find(ch.schema_id);
    if (sc != r.schemas().end()) w_type = std::max(w_type, sc->second.name.size());
  }
  fmt::print("topics:\n");
  for (const auto& [id, ch] : r.channels()) {
    auto sc = r.schemas().find(ch.schema_id);
    const std::string type = sc == r.schemas().end() ? "(no schema)" : sc->second.name;
    auto cnt = st.channel_message_counts.find(id);
    const std::uint64_t n = cnt == st.channel_message_counts.end() ? 0 : cnt->second;
    const bool known = bag::ros2::type_support_for(sc == r.schemas().end() ? nullptr : &sc->second, ch) != nullptr;
    fmt::print("  {:<{}}  {:<{}}  {:>8} msgs  {:>8.1f} Hz{}\n", ch.topic, w_topic, type, w_type, n,
               dur > 0 && n > 1 ? static_cast<double>(n - 1) / dur : 0.0, known ? "" : "  (type unknown to tinyline)");
  }
  for (const auto& mi : sum.metadata_indexes) {
    bag::Metadata md;
    if (r.read_metadata(mi, md).ok()) {
      std::string kv;
      for (const auto& [k, v] : md.metadata) kv += fmt::format("{}{}={}", kv.empty() ? "" : ", ", k, v.empty() ? "\"\"" : v);
      fmt::print("metadata '{}': {}\n", md.name, kv);
    }
  }
  if (!problem.ok()) {
    fmt::print(stderr, "warning: the file is damaged or unfinished: {}\n(run `tinyline bag recover {} FIXED.mcap`)\n",
               problem.str(), path);
    return 1;
  }
  if (a.flag("--verify")) {
    if (bag::Status v = r.verify(); !v.ok()) {
      fmt::print(stderr, "verify: {}\n", v.str());
      return 1;
    }
    fmt::print("verify:       every CRC and count checks out\n");
  }
  return 0;
}

// ---------------------------------------------------------------------------- echo

int cmd_echo(const std::vector<std::string>& argv) {
  Args a(argv, {"--limit"}, {"--full", "--help", "-h"});
  if (a.positional().size() != 2) throw UsageError("expected FILE TOPIC (tinyline bag --help)");
  const std::string path = a.positional()[0];
  const std::string topic = a.positional()[1];
  const auto limit = static_cast<std::uint64_t>(a.number("--limit", 0));
  bag::Reader r;
  if (bag::Status s = r.open(path); !s.ok()) {
    fmt::print(stderr, "{}\n", s.str());
    return 1;
  }
  if (!r.has_summary()) (void)r.scan();
  bool found = false;
  for (const auto& [id, ch] : r.channels()) found = found || ch.topic == topic;
  if (!found) {
    std::string topics;
    for (const auto& [id, ch] : r.channels()) topics += (topics.empty() ? "" : ", ") + ch.topic;
    fmt::print(stderr, "{}: no topic {} (topics: {})\n", path, topic, topics.empty() ? "none" : topics);
    return 1;
  }
  bag::ReadOptions ro;
  ro.topics = {topic};
  std::uint64_t n = 0;
  int rc = 0;
  const bag::Status s = r.for_each(ro, [&](const bag::MessageView& v) {
    std::string why;
    const msg::TypeSupport* ts = bag::ros2::type_support_for(v.schema, *v.channel, &why);
    if (ts == nullptr) {
      fmt::print(stderr, "{}\n", why);
      rc = 1;
      return false;
    }
    fmt::print("--- # {} at {} (seq {})\n", topic, human_time(v.message.log_time), v.message.sequence);
    try {
      auto m = ts->deserialize(v.message.data);
      msg::YamlWriter y(a.flag("--full") ? 0 : 32);
      ts->to_yaml(m.get(), y);
      fmt::print("{}", y.str());
    } catch (const std::exception& e) {
      fmt::print(stderr, "message at {} does not decode: {}\n", v.message.log_time, e.what());
      rc = 1;
    }
    return limit == 0 || ++n < limit;
  });
  if (!s.ok()) {
    fmt::print(stderr, "{}\n", s.str());
    return 1;
  }
  return rc;
}

// ---------------------------------------------------------------------------- recover

int cmd_recover(const std::vector<std::string>& argv) {
  Args a(argv, {"--compression"}, {"--help", "-h"});
  if (a.positional().size() != 2) throw UsageError("expected IN OUT (tinyline bag --help)");
  bag::RecoverOptions ro;
  const auto comp = bag::parse_compression(a.value("--compression").value_or("lz4"));
  if (!comp) throw UsageError("--compression takes none, lz4 or zstd");
  ro.writer.compression = *comp;
  bag::RecoverReport rep;
  const bag::Status s = bag::recover(a.positional()[0], a.positional()[1], ro, rep);
  for (const auto& p : rep.problems) fmt::print("skipped at byte {}: {}\n", p.offset, p.status.str());
  if (!s.ok()) {
    fmt::print(stderr, "{}\n", s.str());
    return 1;
  }
  fmt::print("recovered {} messages on {} channels ({} schemas, {} attachments, {} metadata) from {} chunks of {}",
             rep.messages, rep.channels, rep.schemas, rep.attachments, rep.metadata, rep.chunks, a.positional()[0]);
  fmt::print("; {} chunk(s) skipped; used {} of {} bytes{}\nwrote {}\n", rep.chunks_skipped, rep.bytes_used,
             rep.input_bytes, rep.input_complete ? " (the input was already complete)" : "", a.positional()[1]);
  return 0;
}

// ---------------------------------------------------------------------------- play

int cmd_play(const std::vector<std::string>& argv_in) {
  std::vector<std::string> argv = argv_in;
  const std::vector<std::string> topics = take_list(argv, "--topics");
  Args a(argv, {"--rate", "--start", "--clock-hz", "--duration"}, {"--loop", "--clock", "--help", "-h"});
  if (a.positional().size() != 1) throw UsageError("expected FILE (tinyline bag --help)");
  bag::PlayerOptions po;
  po.path = a.positional()[0];
  po.rate = a.number("--rate", 1.0);
  po.loop = a.flag("--loop");
  po.topics = topics;
  po.start_offset_s = a.number("--start", 0.0);
  po.clock = a.flag("--clock");
  po.clock_hz = a.number("--clock-hz", 100.0);
  if (po.rate < 0) throw UsageError("--rate must be >= 0");
  const double duration = a.number("--duration", 0);
  if (duration < 0) throw UsageError("--duration must be >= 0");
  auto ctx = bus::Context::create(bus::ContextOptions{po.clock ? bus::ClockType::Sim : bus::ClockType::Wall, nullptr});
  bus::NodeOptions no;
  no.name = "player";
  no.context = ctx;
  std::shared_ptr<bag::Player> player;
  try {
    player = std::make_shared<bag::Player>(no, po);
    player->on_start();  // opens the bag: errors before anything runs
  } catch (const std::exception& e) {
    fmt::print(stderr, "{}\n", e.what());
    return 1;
  }
  bus::MultiThreadedExecutor ex(ctx->clock(), 2);
  ex.add_node(player);
  std::thread spinner([&] { ex.spin(); });
  SignalScope sig;
  const auto started = std::chrono::steady_clock::now();
  while (g_signal.load() == 0 && !player->wait_finished(std::chrono::milliseconds(200))) {
    if (duration > 0 && std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count() >= duration) {
      break;
    }
    const auto st = player->stats();
    const double total = static_cast<double>(st.bag_end - st.bag_start) * 1e-9;
    const double at = st.position >= st.bag_start ? static_cast<double>(st.position - st.bag_start) * 1e-9 : 0.0;
    progress(fmt::format("playing {:.1f} / {:.1f} s ({:.0f}%), {} messages{}{}", at, total,
                         total > 0 ? 100.0 * at / total : 100.0, st.published,
                         st.loops > 0 ? fmt::format(", loop {}", st.loops + 1) : std::string(),
                         st.failed > 0 ? fmt::format(", {} failed", st.failed) : std::string()));
  }
  player->stop();
  ex.stop();
  spinner.join();
  progress_done();
  const auto st = player->stats();
  fmt::print("published {} messages from {}{}{}\n", st.published, po.path,
             st.loops > 1 ? fmt::format(" ({} loops)", st.loops) : std::string(),
             st.failed > 0 ? fmt::format("; {} failed", st.failed) : std::string());
  if (!st.status.ok()) {
    fmt::print(stderr, "{}\n", st.status.str());
    return 1;
  }
  return st.failed > 0 ? 1 : 0;
}

// ---------------------------------------------------------------------------- record

int cmd_record(const std::vector<std::string>& argv) {
  Args a(argv, {"-o", "--launch", "--exclude", "--compression", "--chunk-size", "--duration"}, {"--help", "-h"});
  bag::RecorderOptions ro;
  ro.path = a.value("-o").value_or("");
  ro.exclude = a.values("--exclude");
  const auto comp = bag::parse_compression(a.value("--compression").value_or("lz4"));
  if (!comp) throw UsageError("--compression takes none, lz4 or zstd");
  ro.writer.writer.compression = *comp;
  ro.writer.writer.chunk_size_bytes = static_cast<std::uint64_t>(a.number("--chunk-size", 1024)) * 1024;
  launch::LoadOptions lo;
  lo.share_dir = share_dir();
  for (const auto& p : a.positional()) {
    if (p.find(":=") != std::string::npos) {
      lo.args.insert(split_assignment(p));
    } else {
      ro.topics.push_back(p);
    }
  }
  auto ctx = bus::Context::create();
  bus::NodeOptions no;
  no.name = "recorder";
  no.context = ctx;
  std::vector<std::shared_ptr<bus::Node>> nodes;
  std::shared_ptr<bag::Recorder> recorder;
  try {
    recorder = std::make_shared<bag::Recorder>(no, ro);
    nodes.push_back(recorder);
    if (auto file = a.value("--launch")) {
      const auto plan = launch::load_launch_file(*file, lo);
      for (auto& n : launch::instantiate(plan, node_registry(), ctx)) nodes.push_back(std::move(n));
    } else if (!lo.args.empty()) {
      throw UsageError("name:=value arguments need --launch FILE");
    }
    recorder->start();  // creates the file: errors before anything runs
  } catch (const UsageError&) {
    throw;
  } catch (const std::exception& e) {
    fmt::print(stderr, "{}\n", e.what());
    return 1;
  }
  if (nodes.size() == 1) {
    fmt::print(stderr,
               "note: no nodes run in this process, so only topics a transport brings in are recorded; use --launch "
               "FILE, or add a bag/recorder node to your launch file\n");
  }
  bus::MultiThreadedExecutor ex(ctx->clock(), 2);
  for (const auto& n : nodes) ex.add_node(n);
  std::thread spinner([&] { ex.spin(); });
  SignalScope sig;
  const auto start = std::chrono::steady_clock::now();
  const double duration = a.number("--duration", 0);
  while (g_signal.load() == 0) {
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (duration > 0 && elapsed >= duration) break;
    const auto st = recorder->stats();
    progress(fmt::format("recording {:.1f} s: {} topics, {} messages, {}{}", elapsed, st.topics, st.written,
                         human_bytes(st.file_bytes),
                         st.dropped > 0 ? fmt::format(", {} DROPPED", st.dropped) : std::string()));
    std::this_thread::sleep_for(std::chrono::milliseconds(200));  // a CLI waiting for Ctrl-C, not a test
  }
  ex.stop();
  spinner.join();
  progress_done();
  for (auto it = nodes.rbegin(); it != nodes.rend(); ++it) (*it)->on_stop();  // the recorder last: it drains
  const bag::Status s = recorder->stop();
  const auto st = recorder->stats();
  fmt::print("recorded {} messages on {} topics to {} ({}){}\n", st.written, st.topics, recorder->path(),
             human_bytes(st.file_bytes),
             st.dropped > 0 ? fmt::format("; {} messages DROPPED (see the bag's tinyline_recorder metadata)", st.dropped)
                            : std::string());
  if (!s.ok()) {
    fmt::print(stderr, "{}\n", s.str());
    return 1;
  }
  return st.dropped > 0 ? 1 : 0;
}

// ---------------------------------------------------------------------------- dispatch

int cmd_bag(const std::vector<std::string>& argv) {
  if (argv.empty() || argv[0] == "--help" || argv[0] == "-h" || argv[0] == "help") {
    fmt::print("{}", kHelp);
    return argv.empty() ? 2 : 0;
  }
  const std::vector<std::string> rest(argv.begin() + 1, argv.end());
  for (const auto& r : rest) {
    if (r == "--help" || r == "-h") {
      fmt::print("{}", kHelp);
      return 0;
    }
  }
  if (argv[0] == "info") return cmd_info(rest);
  if (argv[0] == "echo") return cmd_echo(rest);
  if (argv[0] == "recover") return cmd_recover(rest);
  if (argv[0] == "play") return cmd_play(rest);
  if (argv[0] == "record") return cmd_record(rest);
  throw UsageError("unknown bag command '" + argv[0] + "' (record, play, info, echo, recover)");
}

const CommandRegistration kBag{"bag", "record, play, inspect and recover MCAP bags", &cmd_bag};

}  // namespace
}  // namespace tinyline::tools
