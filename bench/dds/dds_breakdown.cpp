// SPDX-License-Identifier: Apache-2.0
// Where a round trip's time goes: the ping-pong of dds_bench (pingpong.hpp),
// Cyclone alone and through tinyline's bridges, with a timestamp at every
// stage in both processes (bus/dds/src/probe.hpp, compiled into this
// program's own build of the DDS library only). Prints, per stage, the mean
// and the median over the round trips measured; the means add up to the mean
// round trip.
//
//   dds_breakdown [--round-trips N] [--warm-up N] [--size BYTES]
#include <algorithm>
#include <cstdio>
#include <numeric>

#include "pingpong.hpp"

using namespace tinyline;
using namespace tinyline::bench_dds;
using dds::probe::Stage;
using Marks = std::vector<std::vector<std::int64_t>>;

namespace {

struct Options {
  std::size_t round_trips = 20000;
  std::size_t warm_up = 2000;
  std::size_t size = 64;
};

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i];
    const auto v = static_cast<std::size_t>(std::stoull(argv[i + 1]));
    if (k == "--round-trips") {
      o.round_trips = v;
    } else if (k == "--warm-up") {
      o.warm_up = v;
    } else if (k == "--size") {
      o.size = v;
    } else {
      throw std::invalid_argument("unknown option " + k + " (--round-trips N, --warm-up N, --size BYTES)");
    }
  }
  if ((argc - 1) % 2 != 0) throw std::invalid_argument("options take a value each");
  if (o.round_trips + o.warm_up > dds::probe::kMaxMarks) throw std::invalid_argument("too many round trips");
  return o;
}

/// One segment of a hop: from stage `from` in one process to `to` in one.
struct Segment {
  const char* what;
  bool from_ping, to_ping;  ///< which process marked each end
  Stage from, to;
};

// The stages each path passes, hop 1 (ping -> relay) then hop 2 (relay -> ping).
const std::vector<Segment> kTinyline = {
    {"ping: publish -> bridge tap", true, true, Stage::Publish, Stage::SendEnter},
    {"ping: serialize", true, true, Stage::SendEnter, Stage::Serialized},
    {"Cyclone: write, loopback, relay's receive thread", true, false, Stage::Serialized, Stage::FromSer},
    {"relay: store in the reader, listener, take", false, false, Stage::FromSer, Stage::Taken},
    {"relay: deserialize", false, false, Stage::Taken, Stage::Deserialized},
    {"relay: local publish (queue)", false, false, Stage::Deserialized, Stage::Delivered},
    {"relay: the callback starts (inline, or on a worker)", false, false, Stage::Delivered, Stage::Arrival},
    {"relay: callback -> bridge tap", false, false, Stage::Arrival, Stage::SendEnter},
    {"relay: serialize", false, false, Stage::SendEnter, Stage::Serialized},
    {"Cyclone: write, loopback, ping's receive thread", false, true, Stage::Serialized, Stage::FromSer},
    {"ping: store in the reader, listener, take", true, true, Stage::FromSer, Stage::Taken},
    {"ping: deserialize", true, true, Stage::Taken, Stage::Deserialized},
    {"ping: local publish (queue)", true, true, Stage::Deserialized, Stage::Delivered},
    {"ping: the callback starts (inline, or on a worker)", true, true, Stage::Delivered, Stage::Arrival},
};
const std::vector<Segment> kEngine = {
    {"Cyclone: write, loopback, relay's receive thread", true, false, Stage::Publish, Stage::FromSer},
    {"relay: store in the reader, listener, take", false, false, Stage::FromSer, Stage::Arrival},
    {"Cyclone: write, loopback, ping's receive thread", false, true, Stage::Arrival, Stage::FromSer},
    {"ping: store in the reader, listener, take", true, true, Stage::FromSer, Stage::Arrival},
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

void check_counts(const Marks& m, const std::vector<Segment>& segs, std::size_t n, const char* who, bool ping) {
  for (const auto& s : segs) {
    for (const auto st : {s.from, s.to}) {
      if ((s.from_ping == ping || s.to_ping == ping) && m[static_cast<std::size_t>(st)].size() < n) {
        throw std::runtime_error(fmt::format("{}: stage {} marked {} times, expected {}", who, dds::probe::name(st),
                                             m[static_cast<std::size_t>(st)].size(), n));
      }
    }
  }
}

void report(const char* title, const std::vector<Segment>& segs, const Marks& ping, const Marks& relay,
            const Options& o) {
  const std::size_t n = o.warm_up + o.round_trips;
  check_counts(ping, segs, n, "ping process", true);
  check_counts(relay, segs, n, "relay process", false);
  auto at = [&](bool in_ping, Stage s, std::size_t k) {
    return (in_ping ? ping : relay)[static_cast<std::size_t>(s)][k];
  };
  fmt::print("\n{} ({} B, {} round trips after {} to warm up)\n\n", title, o.size, o.round_trips, o.warm_up);
  fmt::print("| stage | mean us | median us |\n|---|---|---|\n");
  std::vector<double> total(o.round_trips, 0.0);
  for (const auto& s : segs) {
    std::vector<double> d;
    for (std::size_t k = o.warm_up; k < n; ++k) {
      d.push_back(static_cast<double>(at(s.to_ping, s.to, k) - at(s.from_ping, s.from, k)) * 1e-3);
      total[k - o.warm_up] += d.back();
    }
    const double mean = std::accumulate(d.begin(), d.end(), 0.0) / static_cast<double>(d.size());
    fmt::print("| {} | {:.2f} | {:.2f} |\n", s.what, mean, median(d));
  }
  const double mean = std::accumulate(total.begin(), total.end(), 0.0) / static_cast<double>(total.size());
  fmt::print("| **round trip** | **{:.2f}** | **{:.2f}** |\n", mean, median(total));
}

/// Runs the round trips, then stops the pong process (which writes its marks).
template <class Ping>
Marks run(const Options& o, Arrivals& arrivals, Ping&& ping) {
  const std::uint64_t base = arrivals.count.load();
  for (std::size_t k = 1; k <= o.warm_up + o.round_trips; ++k) {
    ping();
    arrivals.wait_for(base + k);
  }
  return dds::probe::marks();
}

Marks relay_marks(const std::string& path) {
  Sessions::get().close();  // the pong process writes its marks as it exits
  Marks m = dds::probe::read(path);
  std::remove(path.c_str());
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  if (const int rc = maybe_pong_main(argc, argv); rc >= 0) return rc;
  try {
    const Options o = parse(argc, argv);
    const std::string path = fmt::format("/tmp/dds_breakdown_{}.marks", getpid());
    setenv("DDS_PROBE_OUT", path.c_str(), 1);

    EnginePinger& e = Sessions::get().engine();
    e.set_payload(o.size);
    dds::probe::reset();
    const Marks engine_ping = run(o, e.arrivals, [&] { e.ping(); });
    report("Cyclone DDS alone (engine)", kEngine, engine_ping, relay_marks(path), o);

    Pinger& t = Sessions::get().tinyline();
    dds::probe::reset();
    const Marks tinyline_ping = run(o, t.arrivals, [&] {
      auto m = cloud(o.size);
      TL_DDS_PROBE(Publish);
      t.pub->publish(std::move(m));
    });
    report("tinyline, two processes through the bridges", kTinyline, tinyline_ping, relay_marks(path), o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dds_breakdown: %s\n", e.what());
    return 1;
  }
  return 0;
}
