// SPDX-License-Identifier: Apache-2.0
// `tinyline calib collect`: bag -> calibration data set (collect.hpp).
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <numbers>
#include <set>
#include <utility>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <tinyline/bag/reader.hpp>
#include <tinyline/msg/tinyline_msgs/raw_scan.hpp>
#include <tinyline/msg/tinyline_msgs/scan_truth.hpp>
#include <tinyline/msg/type_support.hpp>

#include <tiny_laser_calibration/collect.hpp>
#include <tiny_laser_driver/protocol.hpp>

namespace tinyline::tiny_laser_calibration {

using tiny_laser_driver::kPixels;

namespace {

using tinyline_msgs::msg::RawScan;
using tinyline_msgs::msg::ScanTruth;

double seconds(const builtin_interfaces::msg::Time& t) { return t.sec + 1e-9 * t.nanosec; }

// The topic of a type: the one asked for (checked), else the bag's only one.
std::string pick_topic(const bag::Reader& reader, std::string_view type, const std::string& wanted,
                       const std::string& bag_path, std::string& why) {
  std::vector<std::string> found;
  for (const auto& [id, ch] : reader.channels()) {
    const auto s = reader.schemas().find(ch.schema_id);
    if (s == reader.schemas().end() || s->second.name != type) continue;
    if (std::find(found.begin(), found.end(), ch.topic) == found.end()) found.push_back(ch.topic);
  }
  const std::string list = found.empty() ? "none" : fmt::format("{}", fmt::join(found, ", "));
  if (!wanted.empty()) {
    if (std::find(found.begin(), found.end(), wanted) != found.end()) return wanted;
    why = fmt::format("{}: no {} topic '{}' (its {} topics: {})", bag_path, type, wanted, type, list);
    return {};
  }
  if (found.size() == 1) return found.front();
  why = found.empty() ? fmt::format("{}: no {} topic in the bag", bag_path, type)
                      : fmt::format("{}: several {} topics ({}); choose one", bag_path, type, list);
  return {};
}

struct TruthEntry {
  double stamp = 0.0;
  std::shared_ptr<const ScanTruth> msg;
  bool used = false;
};

using StampedScan = std::pair<double, std::shared_ptr<const RawScan>>;

// The bag's messages of both topics, decoded, in log-time order.
struct BagContent {
  std::vector<StampedScan> scans;
  std::vector<TruthEntry> truths;
  std::set<std::string> frames;  ///< frame ids of the raw scans
};

// The bag's own status (its file and stream codes) when it cannot be read.
bool open_bag(bag::Reader& reader, const std::string& bag_path, common::Status& why) {
  if (auto s = reader.open(bag_path); !s.ok()) {
    why = std::move(s);
    return false;
  }
  if (!reader.has_summary()) {
    if (auto s = reader.scan(); !s.ok()) {
      why = std::move(s);
      return false;
    }
  }
  return true;
}

bool read_topics(bag::Reader& reader, CollectResult& out, BagContent& content) {
  bag::ReadOptions ro;
  ro.topics = {out.raw_topic, out.truth_topic};
  std::string decode_error;
  const auto status = reader.for_each(ro, [&](const bag::MessageView& v) {
    if (v.channel->topic == out.raw_topic) {
      auto m = std::make_shared<RawScan>();
      if (const auto d = msg::deserialize(v.message.data, *m); !d) {
        ++out.bad_scans;
        if (decode_error.empty()) decode_error = d.error;
        return true;
      }
      content.frames.insert(m->header.frame_id);
      content.scans.emplace_back(seconds(m->header.stamp), std::move(m));
    } else {
      auto m = std::make_shared<ScanTruth>();
      if (const auto d = msg::deserialize(v.message.data, *m); !d) {
        if (decode_error.empty()) decode_error = d.error;
        return true;
      }
      content.truths.push_back({seconds(m->header.stamp), std::move(m), false});
    }
    return true;
  });
  if (!status.ok()) {
    out.status = status;
    return false;
  }
  if (!decode_error.empty())
    out.notes.push_back(fmt::format("messages that do not decode were skipped: {}", decode_error));
  return true;
}

// Keeps one sensor's sets: the one asked for, else the one frame of the raw scans.
bool keep_one_sensor(const std::string& bag_path, const CollectParams& params, CollectResult& out, BagContent& c) {
  std::string sensor = params.sensor;
  if (sensor.empty()) {
    if (c.frames.size() > 1) {
      out.status = common::Status::invalid(
          fmt::format("{}: topic {} carries several sensors' scans (frames {}); choose one with --sensor", bag_path,
                      out.raw_topic, fmt::join(c.frames, ", ")));
      return false;
    }
    sensor = *c.frames.begin();
  }
  std::erase_if(c.scans, [&](const auto& s) { return s.second->header.frame_id != sensor; });
  std::erase_if(c.truths, [&](const TruthEntry& t) {
    const bool other = t.msg->sensor != sensor && t.msg->header.frame_id != sensor;
    out.other_sensor += other ? 1 : 0;
    return other;
  });
  out.truths = c.truths.size();
  if (c.scans.empty()) {
    out.status = common::Status::not_found(fmt::format("{}: no raw scan of sensor '{}' on {} (frames: {})", bag_path,
                                                       sensor, out.raw_topic, fmt::join(c.frames, ", ")));
    return false;
  }
  if (c.truths.empty()) {
    out.status = common::Status::not_found(
        fmt::format("{}: no ground truth of sensor '{}' on {}", bag_path, sensor, out.truth_topic));
    return false;
  }
  std::sort(c.truths.begin(), c.truths.end(),
            [](const TruthEntry& a, const TruthEntry& b) { return a.stamp < b.stamp; });
  std::stable_sort(c.scans.begin(), c.scans.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return true;
}

// Nearest unused truth within the gap (nullptr when none).
TruthEntry* nearest_truth(std::vector<TruthEntry>& truths, double stamp, double max_gap) {
  const auto it =
      std::lower_bound(truths.begin(), truths.end(), stamp, [](const TruthEntry& t, double s) { return t.stamp < s; });
  TruthEntry* best = nullptr;
  auto consider = [&](TruthEntry& t) {
    if (!t.used && (!best || std::abs(t.stamp - stamp) < std::abs(best->stamp - stamp))) best = &t;
  };
  for (auto j = it; j != truths.end() && j->stamp - stamp <= max_gap; ++j) consider(*j);
  for (auto j = it; j != truths.begin();) {
    --j;
    if (stamp - j->stamp > max_gap) break;
    consider(*j);
  }
  return best;
}

bool sizes_agree(const RawScan& r, const ScanTruth& t) {
  const std::size_t n = r.pixels, k = r.pulses.size();
  return !(n == 0 || n > kPixels || k == 0 || r.a.size() != n * k || r.b.size() != n * k || t.range_m.size() != n ||
           t.flags.size() != n || t.material.size() != n || t.incidence_rad.size() != n);
}

// Whether pixel i of a paired set gives rows; counts the ones left out.
bool pixel_usable(const ScanTruth& t, std::size_t i, const CollectParams& params, int& effective, CollectResult& out) {
  const std::uint8_t f = t.flags[i];
  if (f & ScanTruth::FLAG_DARK) {
    ++out.dark_pixels;
    return false;
  }
  if (effective++ % params.pixel_step != 0) return false;
  const double range = t.range_m[i];
  if (!(std::isfinite(range) && range > 0.0)) {
    ++out.no_range;
    return false;
  }
  if (!(f & ScanTruth::FLAG_LIT)) {
    ++out.unlit;
    return false;
  }
  if ((f & ScanTruth::FLAG_MIXED) && !params.keep_mixed) {
    ++out.mixed;
    return false;
  }
  return true;
}

// One row per read-out of every usable pixel of a paired set.
void add_set_rows(const RawScan& r, const ScanTruth& t, double t_s, const CollectParams& params, CollectResult& out) {
  const std::size_t n = r.pixels, k = r.pulses.size();
  int effective = 0;  // index among the non-dark pixels, for pixel_step
  for (std::size_t i = 0; i < n; ++i) {
    if (!pixel_usable(t, i, params, effective, out)) continue;
    const int mi = t.material[i];
    const std::string material =
        mi >= 0 && static_cast<std::size_t>(mi) < t.materials.size() ? t.materials[static_cast<std::size_t>(mi)] : "";
    for (std::size_t j = 0; j < k; ++j) {
      Readout ro;
      ro.a = tiny_laser_driver::charge_units(r.a[j * n + i]);
      ro.b = tiny_laser_driver::charge_units(r.b[j * n + i]);
      ro.pulses = r.pulses[j];
      ro.temperature_c = r.temperature_c;
      ro.pixel = static_cast<int>(i);
      ro.t_s = t_s;
      if (params.incidence_column) ro.extra.push_back(t.incidence_rad[i] * 180.0 / std::numbers::pi);
      out.data.add(std::move(ro), t.range_m[i], material);
    }
  }
}

void pair_and_add(const std::string& bag_path, const CollectParams& params, CollectResult& out, BagContent& c) {
  CalibrationDataset& data = out.data;
  data.source = bag_path;
  data.has_material = true;
  if (params.incidence_column) data.extra_names.push_back("incidence_deg");
  const double t0 = c.scans.front().first;
  std::size_t sizes_note = 0;
  for (const auto& [stamp, scan] : c.scans) {
    TruthEntry* best = nearest_truth(c.truths, stamp, params.max_pair_gap_s);
    if (!best) {
      ++out.unpaired_scans;
      continue;
    }
    const RawScan& r = *scan;
    const ScanTruth& t = *best->msg;
    if (!sizes_agree(r, t)) {
      ++out.bad_scans;
      if (sizes_note++ == 0) {
        out.notes.push_back(
            fmt::format("raw scan at {:.6f} s left out: {} pixels x {} read-outs, a {} and b {} values, "
                        "truth of {} pixels",
                        stamp, r.pixels, r.pulses.size(), r.a.size(), r.b.size(), t.range_m.size()));
      }
      continue;
    }
    best->used = true;
    ++out.paired;
    add_set_rows(r, t, stamp - t0, params, out);
  }
}

}  // namespace

CollectResult collect_calibration_data(const std::string& bag_path, const CollectParams& params) {
  CollectResult out;
  if (params.pixel_step < 1) {
    out.status = common::Status::invalid(fmt::format("pixel step {} is not a positive integer", params.pixel_step));
    return out;
  }
  if (!(params.max_pair_gap_s >= 0.0)) {
    out.status =
        common::Status::invalid(fmt::format("pairing gap {} s is not a non-negative number", params.max_pair_gap_s));
    return out;
  }
  if (!params.positions_csv.empty()) return collect_rail_positions(bag_path, params);
  bag::Reader reader;
  if (!open_bag(reader, bag_path, out.status)) return out;
  std::string why;
  out.raw_topic = pick_topic(reader, RawScan::kTypeName, params.raw_topic, bag_path, why);
  if (out.raw_topic.empty()) {
    out.status = common::Status::not_found(why);
    return out;
  }
  out.truth_topic = pick_topic(reader, ScanTruth::kTypeName, params.truth_topic, bag_path, why);
  if (out.truth_topic.empty()) {
    out.status = common::Status::not_found(why +
                                           " (record the simulator's scan_truth beside the raw scans, or give a "
                                           "real sensor's rail positions with --positions)");
    return out;
  }
  BagContent content;
  if (!read_topics(reader, out, content)) return out;
  out.raw_scans = content.scans.size() + out.bad_scans;
  if (content.scans.empty()) {
    out.status = common::Status::not_found(fmt::format("{}: topic {} holds no raw scan", bag_path, out.raw_topic));
    return out;
  }
  if (!keep_one_sensor(bag_path, params, out, content)) return out;
  pair_and_add(bag_path, params, out, content);
  if (out.unpaired_scans > 0) {
    out.notes.push_back(fmt::format("{} of {} raw scans had no ground truth within {} s and were left out",
                                    out.unpaired_scans, content.scans.size(), params.max_pair_gap_s));
  }
  if (out.other_sensor > 0) out.notes.push_back(fmt::format("{} truths of other sensors ignored", out.other_sensor));
  if (out.data.empty()) {
    out.status = common::Status::not_found(
        fmt::format("{}: no rows: {} raw scans paired with their truth; pixels left out: {} without a range, "
                    "{} unlit, {} mixed",
                    bag_path, out.paired, out.no_range, out.unlit, out.mixed));
    return out;
  }
  return out;
}

}  // namespace tinyline::tiny_laser_calibration
