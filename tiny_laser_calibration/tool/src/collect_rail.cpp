// SPDX-License-Identifier: Apache-2.0
// `tinyline calib collect --positions LOG.csv`: a real sensor's raw scans on a
// rail with a tape measure -> the calibration data set (collect.hpp). No
// ground-truth topic: the logged distance of the target, per pixel along its ray.
#include <algorithm>
#include <cmath>
#include <memory>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <tinyline/bag/reader.hpp>
#include <tinyline/common/files.hpp>
#include <tinyline/msg/tinyline_msgs/raw_scan.hpp>
#include <tinyline/msg/type_support.hpp>

#include <tiny_laser_calibration/collect.hpp>
#include <tiny_laser_driver/protocol.hpp>
#include <tiny_laser_driver/scan_processor.hpp>

namespace tinyline::tiny_laser_calibration {

namespace {

using tiny_laser_driver::kDarkPixels;
using tiny_laser_driver::kPixels;
using tinyline_msgs::msg::RawScan;

std::vector<std::string> cells_of(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string c;
  while (std::getline(ss, c, ',')) {
    const auto a = c.find_first_not_of(" \t\r"), b = c.find_last_not_of(" \t\r");
    out.push_back(a == std::string::npos ? "" : c.substr(a, b - a + 1));
  }
  return out;
}

double number_cell(const std::string& cell, const std::string& where, const char* column) {
  try {
    std::size_t used = 0;
    const double v = std::stod(cell, &used);
    if (used == cell.size() && std::isfinite(v)) return v;
  } catch (const std::exception&) {}
  throw CalibrationDataError(fmt::format("{}: column '{}': '{}' is not a number", where, column, cell));
}

}  // namespace

std::vector<RailPosition> read_rail_positions(const std::string& path) {
  std::istringstream in;
  try {
    in.str(files::read_text(path, "rail positions", kMaxRailPositionsBytes));
  } catch (const files::FileError& e) {
    throw CalibrationDataError(e.what());
  }
  std::vector<RailPosition> out;
  std::string line;
  std::vector<std::string> header;
  for (std::size_t n = 1; std::getline(in, line); ++n) {
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[line.find_first_not_of(" \t")] == '#') continue;
    const auto cells = cells_of(line);
    const std::string where = fmt::format("{}:{}", path, n);
    if (header.empty()) {
      header = cells;
      if (header.size() < 3 || header[0] != "t_from_s" || header[1] != "t_to_s" || header[2] != "distance_m" ||
          (header.size() > 3 && header[3] != "material") || header.size() > 4) {
        throw CalibrationDataError(
            fmt::format("{}: expected the header t_from_s,t_to_s,distance_m[,material], found '{}'", where, line));
      }
      continue;
    }
    if (cells.size() != header.size()) {
      throw CalibrationDataError(fmt::format("{}: expected {} cells, found {}", where, header.size(), cells.size()));
    }
    RailPosition p{number_cell(cells[0], where, "t_from_s"), number_cell(cells[1], where, "t_to_s"),
                   number_cell(cells[2], where, "distance_m"), cells.size() > 3 ? cells[3] : "", n};
    if (!(p.t_to_s > p.t_from_s)) throw CalibrationDataError(fmt::format("{}: t_to_s must be after t_from_s", where));
    if (!(p.distance_m > 0.0)) throw CalibrationDataError(fmt::format("{}: distance_m must be positive", where));
    out.push_back(p);
  }
  if (out.empty()) throw CalibrationDataError(fmt::format("{}: no rail positions after the header", path));
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.t_from_s < b.t_from_s; });
  for (std::size_t k = 1; k < out.size(); ++k) {
    if (out[k].t_from_s < out[k - 1].t_to_s) {
      throw CalibrationDataError(
          fmt::format("{}:{}: overlaps the position of line {}", path, out[k].line, out[k - 1].line));
    }
  }
  return out;
}

namespace {

const RailPosition* position_at(const std::vector<RailPosition>& ps, double t) {
  for (const auto& p : ps) {
    if (t >= p.t_from_s && t <= p.t_to_s) return &p;
  }
  return nullptr;
}

// The raw scans of one sensor in log order (the sensor asked for, else the bag's only frame).
bool read_raw_scans(const std::string& bag_path, const CollectParams& params, CollectResult& out,
                    std::vector<std::pair<double, RawScan>>& scans) {
  bag::Reader reader;
  if (auto s = reader.open(bag_path); !s.ok()) {
    out.status = std::move(s);
    return false;
  }
  if (!reader.has_summary()) {
    if (auto s = reader.scan(); !s.ok()) {
      out.status = std::move(s);
      return false;
    }
  }
  out.raw_topic = params.raw_topic;
  if (out.raw_topic.empty()) {
    std::set<std::string> topics;
    for (const auto& [id, ch] : reader.channels()) {
      const auto sc = reader.schemas().find(ch.schema_id);
      if (sc != reader.schemas().end() && sc->second.name == RawScan::kTypeName) topics.insert(ch.topic);
    }
    if (topics.size() != 1) {
      out.status =
          topics.empty()
              ? common::Status::not_found(fmt::format("{}: no {} topic in the bag", bag_path, RawScan::kTypeName))
              : common::Status::invalid(
                    fmt::format("{}: several raw scan topics ({}); choose one", bag_path, fmt::join(topics, ", ")));
      return false;
    }
    out.raw_topic = *topics.begin();
  }
  bag::ReadOptions ro;
  ro.topics = {out.raw_topic};
  std::set<std::string> frames;
  const auto status = reader.for_each(ro, [&](const bag::MessageView& v) {
    RawScan m;
    if (!msg::deserialize(v.message.data, m)) {
      ++out.bad_scans;
      return true;
    }
    frames.insert(m.header.frame_id);
    scans.emplace_back(m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec, std::move(m));
    return true;
  });
  if (!status.ok()) {
    out.status = status;
    return false;
  }
  out.raw_scans = scans.size() + out.bad_scans;
  if (params.sensor.empty() && frames.size() > 1) {
    out.status = common::Status::invalid(
        fmt::format("{}: topic {} carries several sensors' scans (frames {}); choose one with --sensor", bag_path,
                    out.raw_topic, fmt::join(frames, ", ")));
    return false;
  }
  if (!params.sensor.empty())
    std::erase_if(scans, [&](const auto& s) { return s.second.header.frame_id != params.sensor; });
  std::stable_sort(scans.begin(), scans.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  if (scans.empty())
    out.status = common::Status::not_found(fmt::format("{}: no raw scan on {}", bag_path, out.raw_topic));
  return !scans.empty();
}

void add_rail_rows(const RawScan& r, double t_s, const RailPosition& pos, const CollectParams& params,
                   const tiny_laser_driver::OpticsParams& optics, CollectResult& out) {
  const std::size_t n = r.pixels, k = r.pulses.size();
  const int first = params.pixel_from >= 0 ? params.pixel_from : static_cast<int>(kDarkPixels);
  const int last = params.pixel_to >= 0 ? params.pixel_to : static_cast<int>(kPixels - kDarkPixels) - 1;
  int effective = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (i < kDarkPixels || i >= kPixels - kDarkPixels) {
      ++out.dark_pixels;
      continue;
    }
    if (effective++ % params.pixel_step != 0 || static_cast<int>(i) < first || static_cast<int>(i) > last) continue;
    // A flat target square to the axis at the logged distance: the ray of pixel i meets it at D / cos(angle).
    const double range = pos.distance_m / std::cos(tiny_laser_driver::pixel_angle_rad(optics, i));
    for (std::size_t j = 0; j < k; ++j) {
      Readout ro;
      ro.a = tiny_laser_driver::charge_units(r.a[j * n + i]);
      ro.b = tiny_laser_driver::charge_units(r.b[j * n + i]);
      ro.pulses = r.pulses[j];
      ro.temperature_c = r.temperature_c;
      ro.pixel = static_cast<int>(i);
      ro.t_s = t_s;
      out.data.add(std::move(ro), range, pos.material);
    }
  }
}

}  // namespace

CollectResult collect_rail_positions(const std::string& bag_path, const CollectParams& params) {
  CollectResult out;
  std::vector<RailPosition> positions;
  try {
    positions = read_rail_positions(params.positions_csv);
  } catch (const CalibrationDataError& e) {
    out.status = common::Status::invalid(e.what());
    return out;
  }
  tiny_laser_driver::OpticsParams optics;
  optics.focal_mm = params.focal_mm;
  optics.sensor_length_mm = params.sensor_length_mm;
  if (common::Status why = optics.validate(); !why.ok()) {
    out.status = why.within("optics");
    return out;
  }
  std::vector<std::pair<double, RawScan>> scans;
  if (!read_raw_scans(bag_path, params, out, scans)) return out;
  out.data.source = bag_path;
  out.data.has_material =
      std::any_of(positions.begin(), positions.end(), [](const auto& p) { return !p.material.empty(); });
  const double t0 = scans.front().first;
  for (const auto& [stamp, r] : scans) {
    const std::size_t n = r.pixels, k = r.pulses.size();
    if (n != kPixels || k == 0 || r.a.size() != n * k || r.b.size() != n * k) {
      ++out.bad_scans;
      continue;
    }
    const RailPosition* pos = position_at(positions, stamp - t0);
    if (!pos) {
      ++out.between_positions;
      continue;
    }
    ++out.paired;
    add_rail_rows(r, stamp - t0, *pos, params, optics, out);
  }
  if (out.between_positions > 0) {
    out.notes.push_back(
        fmt::format("{} raw scans fell outside every logged rail position (the target moving) and were "
                    "left out",
                    out.between_positions));
  }
  if (out.data.empty()) {
    out.status = common::Status::not_found(fmt::format("{}: no raw scan of {} lies inside a position of {}", bag_path,
                                                       out.raw_topic, params.positions_csv));
    return out;
  }
  return out;
}

}  // namespace tinyline::tiny_laser_calibration
