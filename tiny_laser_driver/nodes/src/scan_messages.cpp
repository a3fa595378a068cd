// SPDX-License-Identifier: Apache-2.0
#include <tiny_laser_driver/nodes/scan_messages.hpp>

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include <fmt/format.h>

namespace tinyline::tiny_laser_driver {

namespace {
constexpr double kRangeMinM = 0.05;  // the sensor's range
constexpr double kRangeMaxM = 3.0;   // the outer limit quoted beside it
}  // namespace

std::unique_ptr<tinyline_msgs::msg::RawScan> to_raw_scan(const RawSet& set, bus::Time stamp,
                                                         const std::string& frame_id) {
  auto m = std::make_unique<tinyline_msgs::msg::RawScan>();
  m->header.stamp = stamp.to_msg();
  m->header.frame_id = frame_id;
  m->set_index = static_cast<std::uint32_t>(set.sequence);
  m->temperature_c = static_cast<float>(set.temperature_decic() / 10.0);
  m->pixels = static_cast<std::uint16_t>(kPixels);
  m->pulses.reserve(set.frames.size());
  m->a.resize(set.frames.size() * kPixels);
  m->b.resize(set.frames.size() * kPixels);
  for (std::size_t k = 0; k < set.frames.size(); ++k) {
    const RawFrame& f = set.frames[k];
    m->pulses.push_back(f.pulses);
    std::memcpy(m->a.data() + k * kPixels, f.a.data(), kPixels * sizeof(std::int16_t));
    std::memcpy(m->b.data() + k * kPixels, f.b.data(), kPixels * sizeof(std::int16_t));
  }
  return m;
}

std::optional<RawSet> from_raw_scan(const tinyline_msgs::msg::RawScan& m, std::string* why) {
  auto fail = [&](std::string text) -> std::optional<RawSet> {
    if (why) *why = std::move(text);
    return std::nullopt;
  };
  if (m.pixels != kPixels) return fail(fmt::format("RawScan with {} pixels; this sensor has {}", m.pixels, kPixels));
  const std::size_t n = m.pulses.size();
  if (n == 0 || n >= kLastFrameFlag) return fail(fmt::format("RawScan with {} read-outs (expected 1-99)", n));
  if (m.a.size() != n * kPixels || m.b.size() != n * kPixels) {
    return fail(fmt::format("RawScan arrays a[{}] and b[{}] do not hold {} read-outs of {} pixels", m.a.size(),
                            m.b.size(), n, kPixels));
  }
  if (!std::isfinite(m.temperature_c) || m.temperature_c < 0.0f || m.temperature_c > 6553.5f) {
    return fail(fmt::format("RawScan temperature {} degC cannot be a sensor reading", m.temperature_c));
  }
  RawSet set;
  set.sequence = m.set_index;
  set.frames.resize(n);
  const auto decic = static_cast<std::uint16_t>(std::lround(m.temperature_c * 10.0));
  for (std::size_t k = 0; k < n; ++k) {
    RawFrame& f = set.frames[k];
    if (m.pulses[k] == 0 || (k > 0 && m.pulses[k] <= m.pulses[k - 1])) {
      return fail(fmt::format("RawScan pulses must rise from a positive count; read-out {} has {}", k, m.pulses[k]));
    }
    f.index = static_cast<std::uint16_t>(k);
    f.last = k + 1 == n;
    f.pulses = m.pulses[k];
    f.temperature_decic = decic;
    std::memcpy(f.a.data(), m.a.data() + k * kPixels, kPixels * sizeof(std::int16_t));
    std::memcpy(f.b.data(), m.b.data() + k * kPixels, kPixels * sizeof(std::int16_t));
  }
  return set;
}

ScanMessages::ScanMessages(const ScanProcessor& processor, std::string frame_id, std::string scan_frame_id)
    : angles_(processor.angles_rad().begin(), processor.angles_rad().end()),
      layout_(uniform_scan_layout(processor.angles_rad())),
      frame_id_(std::move(frame_id)),
      scan_frame_id_(std::move(scan_frame_id)) {}

std::unique_ptr<tinyline_msgs::msg::LineScan> ScanMessages::line(const ProcessedScan& scan, std::uint32_t index,
                                                                 bus::Time stamp, float temperature_c) const {
  auto line = std::make_unique<tinyline_msgs::msg::LineScan>();
  line->header.stamp = stamp.to_msg();
  line->header.frame_id = frame_id_;
  line->set_index = index;
  line->temperature_c = temperature_c;
  line->angles = angles_;
  line->distance_m.assign(scan.distance_m.begin(), scan.distance_m.end());
  line->range_sd_m.assign(scan.range_sd_m.begin(), scan.range_sd_m.end());
  line->intensity.assign(scan.intensity.begin(), scan.intensity.end());
  line->reflectance.assign(scan.reflectance.begin(), scan.reflectance.end());
  line->pulses.assign(scan.pulses.begin(), scan.pulses.end());
  line->status.resize(kPixels);
  for (std::size_t p = 0; p < kPixels; ++p) line->status[p] = static_cast<std::uint8_t>(scan.status[p]);
  return line;
}

std::unique_ptr<sensor_msgs::msg::LaserScan> ScanMessages::laser(const ProcessedScan& scan, bus::Time stamp,
                                                                 double scan_time_s) const {
  auto ls = std::make_unique<sensor_msgs::msg::LaserScan>();
  ls->header.stamp = stamp.to_msg();
  ls->header.frame_id = scan_frame_id_;
  ls->angle_min = static_cast<float>(layout_.angle_min_rad);
  ls->angle_max = static_cast<float>(layout_.angle_max_rad);
  ls->angle_increment = static_cast<float>(layout_.angle_increment_rad);
  ls->time_increment = 0.0f;  // every pixel integrates at once
  ls->scan_time = static_cast<float>(scan_time_s);
  ls->range_min = static_cast<float>(kRangeMinM);
  ls->range_max = static_cast<float>(kRangeMaxM);
  ls->ranges.resize(layout_.pixel_of_bin.size());
  ls->intensities.resize(layout_.pixel_of_bin.size());
  for (std::size_t i = 0; i < layout_.pixel_of_bin.size(); ++i) {
    const std::size_t p = layout_.pixel_of_bin[i];
    switch (scan.status[p]) {
      case PixelStatus::kValid: ls->ranges[i] = scan.distance_m[p]; break;
      case PixelStatus::kTooDark: ls->ranges[i] = std::numeric_limits<float>::infinity(); break;
      default: ls->ranges[i] = std::numeric_limits<float>::quiet_NaN(); break;
    }
    ls->intensities[i] = std::isfinite(scan.intensity[p]) ? scan.intensity[p] : 0.0f;
  }
  return ls;
}

namespace {

std::vector<sensor_msgs::msg::PointField> xyzi_fields() {
  std::vector<sensor_msgs::msg::PointField> fields;
  std::uint32_t offset = 0;
  for (const char* name : {"x", "y", "z", "intensity"}) {
    sensor_msgs::msg::PointField f;
    f.name = name;
    f.offset = offset;
    f.datatype = sensor_msgs::msg::PointField::FLOAT32;
    f.count = 1;
    fields.push_back(std::move(f));
    offset += sizeof(float);
  }
  return fields;
}

}  // namespace

std::unique_ptr<sensor_msgs::msg::PointCloud2> ScanMessages::cloud(const ProcessedScan& scan, bus::Time stamp) const {
  constexpr std::uint32_t kStep = 4 * sizeof(float);
  auto c = std::make_unique<sensor_msgs::msg::PointCloud2>();
  c->header.stamp = stamp.to_msg();
  c->header.frame_id = frame_id_;
  c->height = 1;
  c->width = static_cast<std::uint32_t>(kPixels);
  c->fields = xyzi_fields();
  c->is_bigendian = std::endian::native == std::endian::big;  // the floats are copied as they are
  c->point_step = kStep;
  c->row_step = kStep * c->width;
  c->is_dense = false;
  c->data.resize(static_cast<std::size_t>(c->row_step));
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  for (std::size_t p = 0; p < kPixels; ++p) {
    const bool valid = scan.status[p] == PixelStatus::kValid;
    const float r = scan.distance_m[p];
    // The pixel's ray lies in the sensor's x-z plane, `angles_[p]` from z towards +x.
    const float point[4] = {valid ? r * std::sin(angles_[p]) : kNaN, valid ? 0.0f : kNaN,
                            valid ? r * std::cos(angles_[p]) : kNaN,
                            std::isfinite(scan.intensity[p]) ? scan.intensity[p] : 0.0f};
    std::memcpy(c->data.data() + p * kStep, point, kStep);
  }
  return c;
}

}  // namespace tinyline::tiny_laser_driver
