// SPDX-License-Identifier: Apache-2.0
// tinyline bag record|play|info|echo|recover: MCAP bags from the command line.
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <memory>

#include <fmt/format.h>

#include <tinyline/bag/player.hpp>
#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/recorder.hpp>
#include <tinyline/bag/recover.hpp>
#include <tinyline/common/visible_text.hpp>
#include <tinyline/bag/ros2.hpp>
#include <tinyline/launch/launch.hpp>
#include <tinyline/msg/yaml_writer.hpp>
#include <tinyline/tools/command.hpp>

#include "../src/parsing.hpp"
#include "../src/graph_runner.hpp"

namespace tinyline::tools {
namespace {

using common::visible;

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

cli::Option* add_compression(cli::App& cmd, std::string& value) {
  return cmd.add_option("--compression", value, "chunk compression")
      ->capture_default_str()
      ->check(cli::one_of({"none", "lz4", "zstd"}));
}

// Opens a bag, printing why not on stderr.
bool open_bag(bag::Reader& r, const std::string& path) {
  if (bag::Status s = r.open(path); !s.ok()) {
    fmt::print(stderr, "{}\n", s.str());
    return false;
  }
  return true;
}

// ---------------------------------------------------------------------------- info

// File, profile, times, counts, chunks and their compression.
void print_overview(const bag::Reader& r, const std::string& path) {
  const auto& sum = r.summary();
  const auto& st = sum.statistics;
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  fmt::print("file:         {} ({}, {}, {})\n", path, human_bytes(ec ? 0 : size),
             r.complete() ? "complete" : "NOT complete: no footer",
             r.has_summary() ? "indexed" : "no summary, scanned");
  fmt::print("profile:      {} (written by {})\n", sum.header.profile.empty() ? "(none)" : visible(sum.header.profile),
             visible(sum.header.library));
  if (st.message_count > 0) {
    fmt::print("start:        {}\nend:          {}\nduration:     {:.3f} s\n", human_time(st.message_start_time),
               human_time(st.message_end_time),
               static_cast<double>(st.message_end_time - st.message_start_time) * 1e-9);
  }
  fmt::print("messages:     {}\n", st.message_count);
  std::string comp;
  for (const auto& [c, n] : sum.chunks_by_compression) {
    comp += fmt::format("{}{}: {}", comp.empty() ? "" : ", ", c.empty() ? "none" : visible(c), n);
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
}

// One line per topic: type, count, rate, and whether tinyline knows the type.
void print_topics(const bag::Reader& r) {
  const auto& st = r.summary().statistics;
  const double dur = static_cast<double>(st.message_end_time - st.message_start_time) * 1e-9;
  auto schema_of = [&](const bag::Channel& ch) {
    auto sc = r.schemas().find(ch.schema_id);
    return sc == r.schemas().end() ? nullptr : &sc->second;
  };
  std::size_t w_topic = 5, w_type = 4;
  for (const auto& [id, ch] : r.channels()) {
    w_topic = std::max(w_topic, visible(ch.topic).size());
    if (const auto* sc = schema_of(ch)) w_type = std::max(w_type, visible(sc->name).size());
  }
  fmt::print("topics:\n");
  for (const auto& [id, ch] : r.channels()) {
    const bag::Schema* sc = schema_of(ch);
    auto cnt = st.channel_message_counts.find(id);
    const std::uint64_t n = cnt == st.channel_message_counts.end() ? 0 : cnt->second;
    const bool known = bag::ros2::type_support_for(sc, ch) != nullptr;
    fmt::print("  {:<{}}  {:<{}}  {:>8} msgs  {:>8.1f} Hz{}\n", visible(ch.topic), w_topic,
               sc ? visible(sc->name) : "(no schema)", w_type, n,
               dur > 0 && n > 1 ? static_cast<double>(n - 1) / dur : 0.0, known ? "" : "  (type unknown to tinyline)");
  }
}

void print_metadata(bag::Reader& r) {
  for (const auto& mi : r.summary().metadata_indexes) {
    bag::Metadata md;
    if (!r.read_metadata(mi, md).ok()) continue;
    std::string kv;
    for (const auto& [k, v] : md.metadata)
      kv += fmt::format("{}{}={}", kv.empty() ? "" : ", ", visible(k), v.empty() ? "\"\"" : visible(v));
    fmt::print("metadata '{}': {}\n", visible(md.name), kv);
  }
}

int info(const std::string& path, bool verify) {
  bag::Reader r;
  if (!open_bag(r, path)) return 1;
  bag::Status problem;
  if (!r.has_summary()) problem = r.scan();
  print_overview(r, path);
  print_topics(r);
  print_metadata(r);
  if (!problem.ok()) {
    fmt::print(stderr, "warning: the file is damaged or unfinished: {}\n(run `tinyline bag recover {} FIXED.mcap`)\n",
               problem.str(), path);
    return 1;
  }
  if (verify) {
    if (bag::Status v = r.verify(); !v.ok()) {
      fmt::print(stderr, "verify: {}\n", v.str());
      return 1;
    }
    fmt::print("verify:       every CRC and count checks out\n");
  }
  return 0;
}

CommandRun setup_info(cli::App& cmd) {
  auto path = std::make_shared<std::string>();
  auto verify = std::make_shared<bool>(false);
  cmd.add_option("file", *path, "the bag")->required();
  cmd.add_flag("--verify", *verify, "also read every record and check every CRC and count");
  cmd.footer("Topics, types, counts, duration and compression of a bag.");
  return [path, verify] { return info(*path, *verify); };
}

// ---------------------------------------------------------------------------- echo

struct EchoArgs {
  std::string path;
  std::string topic;
  std::int64_t limit = 0;
  bool full = false;
};

// Prints one message as YAML; false when its type is unknown (stop).
bool echo_one(const bag::MessageView& v, const EchoArgs& a, int& rc) {
  std::string why;
  const msg::TypeSupport* ts = bag::ros2::type_support_for(v.schema, *v.channel, &why);
  if (ts == nullptr) {
    fmt::print(stderr, "{}\n", why);
    rc = 1;
    return false;
  }
  fmt::print("--- # {} at {} (seq {})\n", a.topic, human_time(v.message.log_time), v.message.sequence);
  try {
    auto m = ts->deserialize(v.message.data);
    msg::YamlWriter y(a.full ? 0 : 32);
    ts->to_yaml(m.get(), y);
    fmt::print("{}", y.str());
  } catch (const std::exception& e) {
    fmt::print(stderr, "message at {} does not decode: {}\n", v.message.log_time, e.what());
    rc = 1;
  }
  return true;
}

int echo(const EchoArgs& a) {
  bag::Reader r;
  if (!open_bag(r, a.path)) return 1;
  if (!r.has_summary()) (void)r.scan();
  std::string topics;
  bool found = false;
  for (const auto& [id, ch] : r.channels()) {
    found = found || ch.topic == a.topic;
    topics += (topics.empty() ? "" : ", ") + ch.topic;
  }
  if (!found) {
    fmt::print(stderr, "{}: no topic {} (topics: {})\n", a.path, a.topic, topics.empty() ? "none" : topics);
    return 1;
  }
  bag::ReadOptions ro;
  ro.topics = {a.topic};
  std::int64_t n = 0;
  int rc = 0;
  const bag::Status s =
      r.for_each(ro, [&](const bag::MessageView& v) { return echo_one(v, a, rc) && (a.limit == 0 || ++n < a.limit); });
  if (!s.ok()) {
    fmt::print(stderr, "{}\n", s.str());
    return 1;
  }
  return rc;
}

CommandRun setup_echo(cli::App& cmd) {
  auto a = std::make_shared<EchoArgs>();
  cmd.add_option("file", a->path, "the bag")->required();
  cmd.add_option("topic", a->topic, "the topic to print")->required();
  cmd.add_option("--limit", a->limit, "print at most N messages (0: all)")->check(cli::count());
  cmd.add_flag("--full", a->full, "print long arrays whole (default: the first 32 elements)");
  cmd.footer("Prints a topic's messages as YAML.");
  return [a] { return echo(*a); };
}

// ---------------------------------------------------------------------------- recover

struct RecoverArgs {
  std::string in;
  std::string out;
  std::string compression = "lz4";
};

int recover(const RecoverArgs& a) {
  bag::RecoverOptions ro;
  ro.writer.compression = *bag::parse_compression(a.compression);
  bag::RecoverReport rep;
  const bag::Status s = bag::recover(a.in, a.out, ro, rep);
  for (const auto& p : rep.problems) fmt::print("skipped at byte {}: {}\n", p.offset, p.status.str());
  if (!s.ok()) {
    fmt::print(stderr, "{}\n", s.str());
    return 1;
  }
  fmt::print("recovered {} messages on {} channels ({} schemas, {} attachments, {} metadata) from {} chunks of {}",
             rep.messages, rep.channels, rep.schemas, rep.attachments, rep.metadata, rep.chunks, a.in);
  fmt::print("; {} chunk(s) skipped; used {} of {} bytes{}\nwrote {}\n", rep.chunks_skipped, rep.bytes_used,
             rep.input_bytes, rep.input_complete ? " (the input was already complete)" : "", a.out);
  return 0;
}

CommandRun setup_recover(cli::App& cmd) {
  auto a = std::make_shared<RecoverArgs>();
  cmd.add_option("in", a->in, "the damaged or unfinished bag")->required();
  cmd.add_option("out", a->out, "the complete bag to write (an existing file is replaced only on success)")->required();
  add_compression(cmd, a->compression);
  cmd.footer("Rewrites what is readable in a damaged or unfinished bag as a complete one.");
  return [a] { return recover(*a); };
}

// ---------------------------------------------------------------------------- play

struct PlayArgs {
  bag::PlayerOptions player;
  std::optional<double> duration_s;
};

std::string play_progress(const bag::PlayerStats& st) {
  const double total = static_cast<double>(st.bag_end - st.bag_start) * 1e-9;
  const double at = st.position >= st.bag_start ? static_cast<double>(st.position - st.bag_start) * 1e-9 : 0.0;
  return fmt::format("playing {:.1f} / {:.1f} s ({:.0f}%), {} messages{}{}", at, total,
                     total > 0 ? 100.0 * at / total : 100.0, st.published,
                     st.loops > 0 ? fmt::format(", loop {}", st.loops + 1) : std::string(),
                     st.failed > 0 ? fmt::format(", {} failed", st.failed) : std::string());
}

int play(const PlayArgs& a) {
  const bag::PlayerOptions& po = a.player;
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
  RunOptions ro;
  ro.duration_s = a.duration_s;
  ro.table = false;
  ro.summary = false;
  ro.tick = [&](std::chrono::milliseconds budget) {
    progress(play_progress(player->stats()));
    return !player->wait_finished(budget);
  };
  int rc = run_nodes(ctx, {player}, ro);
  progress_done();
  const auto st = player->stats();
  fmt::print("published {} messages from {}{}{}\n", st.published, po.path,
             st.loops > 1 ? fmt::format(" ({} loops)", st.loops) : std::string(),
             st.failed > 0 ? fmt::format("; {} failed", st.failed) : std::string());
  if (!st.status.ok()) {
    fmt::print(stderr, "{}\n", st.status.str());
    rc = 1;
  }
  return st.failed > 0 ? 1 : rc;
}

CommandRun setup_play(cli::App& cmd) {
  auto a = std::make_shared<PlayArgs>();
  bag::PlayerOptions& p = a->player;
  cmd.add_option("file", p.path, "the bag")->required();
  cmd.add_option("--rate", p.rate, "playback speed, x real time (0: as fast as possible)")
      ->capture_default_str()
      ->check(cli::non_negative());
  cmd.add_flag("--loop", p.loop, "start over at the end");
  cmd.add_option("--topics", p.topics, "play only these topics (T T ... or T,T)")->delimiter(',')->expected(1, 10000);
  cmd.add_option("--start", p.start_offset_s, "skip the first S seconds of the bag")
      ->type_name("S")
      ->check(cli::non_negative());
  cmd.add_flag("--clock", p.clock, "publish /clock (rosgraph_msgs/Clock) and drive sim time");
  cmd.add_option("--clock-hz", p.clock_hz, "/clock rate between messages")
      ->capture_default_str()
      ->check(cli::finite_above(0.1, true, 10000.0));
  cmd.add_option("--duration", a->duration_s,
                 "stop after S seconds of playing (default: the bag's end, or Ctrl-C with --loop)")
      ->type_name("S")
      ->check(cli::seconds());
  cmd.footer("Publishes a bag's messages on their topics.");
  return [a] { return play(*a); };
}

// ---------------------------------------------------------------------------- record

struct RecordArgs {
  std::string path;
  std::vector<std::string> positionals;  // topics and name:=value for --launch
  std::string launch_file;
  std::vector<std::string> exclude;
  std::string compression = "lz4";
  std::uint64_t chunk_kib = 1024;
  std::optional<double> duration_s;
};

// The recorder and, with --launch, the nodes of the launch file; nothing runs yet.
std::vector<std::shared_ptr<bus::Node>> record_nodes(const RecordArgs& a, const std::shared_ptr<bus::Context>& ctx,
                                                     std::shared_ptr<bag::Recorder>& recorder) {
  bag::RecorderOptions ro;
  ro.path = a.path;
  ro.exclude = a.exclude;
  ro.writer.writer.compression = *bag::parse_compression(a.compression);
  ro.writer.writer.chunk_size_bytes = a.chunk_kib * 1024;
  launch::LoadOptions lo;
  lo.share_dir = share_dir();
  for (const auto& p : a.positionals) {
    if (p.find(":=") != std::string::npos) {
      lo.args.insert(parsing::split_assignment(p));
    } else {
      ro.topics.push_back(p);
    }
  }
  if (a.launch_file.empty() && !lo.args.empty()) throw UsageError("name:=value arguments need --launch FILE");
  if (!a.launch_file.empty()) ro.writer.inputs = {a.launch_file};
  bus::NodeOptions no;
  no.name = "recorder";
  no.context = ctx;
  recorder = std::make_shared<bag::Recorder>(no, ro);
  std::vector<std::shared_ptr<bus::Node>> nodes{recorder};
  if (!a.launch_file.empty()) {
    const auto plan = launch::load_launch_file(a.launch_file, lo);
    auto launched = launch::instantiate(plan, node_registry(), ctx);
    launch::configure(plan, launched);
    nodes.insert(nodes.end(), launched.begin(), launched.end());
    launch::check_files(nodes);  // the recorder's file against the launch file's nodes too
  }
  return nodes;
}

int record(const RecordArgs& a) {
  auto ctx = bus::Context::create();
  std::shared_ptr<bag::Recorder> recorder;
  std::vector<std::shared_ptr<bus::Node>> nodes;
  try {
    nodes = record_nodes(a, ctx, recorder);
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
  RunOptions ro;
  ro.duration_s = a.duration_s;
  ro.table = false;
  ro.summary = false;
  ro.progress = [&](double elapsed) {
    const auto st = recorder->stats();
    progress(fmt::format("recording {:.1f} s: {} topics, {} messages, {}{}", elapsed, st.topics, st.written,
                         human_bytes(st.file_bytes),
                         st.dropped > 0 ? fmt::format(", {} DROPPED", st.dropped) : std::string()));
  };
  const int rc = run_nodes(ctx, nodes, ro);  // stops the recorder last: it drains and finishes the file
  progress_done();
  const auto st = recorder->stats();
  fmt::print("recorded {} messages on {} topics to {} ({}){}\n", st.written, st.topics, recorder->path(),
             human_bytes(st.file_bytes),
             st.dropped > 0
                 ? fmt::format("; {} messages DROPPED (see the bag's tinyline_recorder metadata)", st.dropped)
                 : std::string());
  return rc != 0 || st.dropped > 0 ? 1 : 0;
}

CommandRun setup_record(cli::App& cmd) {
  auto a = std::make_shared<RecordArgs>();
  cmd.add_option("topics", a->positionals,
                 "topics to record (all by default; relative names resolve against /); with --launch, name:=value "
                 "arguments of the launch file");
  cmd.add_option("-o", a->path, "output file (default tinyline_<date>_<time>.mcap)")->type_name("FILE");
  cmd.add_option("--launch", a->launch_file, "run this launch file in the same process and record its topics")
      ->type_name("FILE");
  cmd.add_option("--exclude", a->exclude, "do not record TOPIC (repeatable)")
      ->type_name("TOPIC")
      ->allow_extra_args(false);
  add_compression(cmd, a->compression);
  cmd.add_option("--chunk-size", a->chunk_kib, "uncompressed chunk size [KiB]")
      ->capture_default_str()
      ->check(cli::whole(1, 1 << 20));
  cmd.add_option("--duration", a->duration_s, "stop after S seconds (default: Ctrl-C)")
      ->type_name("S")
      ->check(cli::seconds());
  cmd.footer(
      "`bag record` records the topics of its own process: those of --launch, and those a transport bridges in.\n"
      "To record inside a running launch file, add a node {pkg: bag, exec: recorder} to it (parameters:\n"
      "tinyline describe bag/recorder). The file is written as FILE.part and renamed to FILE when it is finished.");
  return [a] { return record(*a); };
}

// ---------------------------------------------------------------------------- the group

CommandRun setup_bag(cli::App& cmd) {
  return parsing::nested(cmd, {{"record", "record topics (all by default) to an MCAP bag", &setup_record},
                               {"play", "publish a bag's messages on their topics", &setup_play},
                               {"info", "topics, types, counts, duration, compression", &setup_info},
                               {"echo", "print a topic's messages as YAML", &setup_echo},
                               {"recover", "rewrite a damaged or unfinished bag as a complete one", &setup_recover}});
}

const CommandRegistration kBag{"bag", "record, play, inspect and recover MCAP bags", &setup_bag};

}  // namespace
}  // namespace tinyline::tools
