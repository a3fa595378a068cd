// SPDX-License-Identifier: Apache-2.0
// Deterministic sample traffic for bag tests: one topic per message shape the
// project records (raw and calibrated line scans with NaNs, laser scans, point
// clouds, joint states, markers with nested lists and UTF-8 text,
// diagnostics, poses, strings with characters that need escaping, clock), and
// the expected-values file the Python interop checks compare against.
#pragma once

#include <cmath>
#include <fstream>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <tinyline/bag/ros2.hpp>
#include <tinyline/msg/diagnostic_msgs/diagnostic_array.hpp>
#include <tinyline/msg/geometry_msgs/pose_stamped.hpp>
#include <tinyline/msg/point_cloud.hpp>
#include <tinyline/msg/rosgraph_msgs/clock.hpp>
#include <tinyline/msg/sensor_msgs/joint_state.hpp>
#include <tinyline/msg/sensor_msgs/laser_scan.hpp>
#include <tinyline/msg/sensor_msgs/point_cloud2.hpp>
#include <tinyline/msg/std_msgs/string.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>
#include <tinyline/msg/tinyline_msgs/raw_scan.hpp>
#include <tinyline/msg/visualization_msgs/marker_array.hpp>
#include <tinyline/msg/yaml_writer.hpp>

namespace tinyline::bag::testing {

struct SampleMessage {
  std::string topic;
  const msg::TypeSupport* type = nullptr;
  std::shared_ptr<const void> message;
  Timestamp log_time = 0;
  Timestamp publish_time = 0;
  std::uint32_t sequence = 0;
};

inline builtin_interfaces::msg::Time stamp_of(Timestamp t) {
  builtin_interfaces::msg::Time s;
  s.sec = static_cast<std::int32_t>(t / 1'000'000'000);
  s.nanosec = static_cast<std::uint32_t>(t % 1'000'000'000);
  return s;
}

template <class T>
void add(std::vector<SampleMessage>& out, std::string topic, std::shared_ptr<T> m, Timestamp t, std::uint32_t seq) {
  out.push_back({std::move(topic), &msg::type_support<T>(), std::move(m), t, t - 1000, seq});
}

/// `steps` rounds of every topic, 10 ms apart, starting at `t0` [ns].
inline std::vector<SampleMessage> sample_traffic(int steps, std::uint32_t seed = 1,
                                                 Timestamp t0 = 1'700'000'000'000'000'000ULL) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uf(-3.0F, 3.0F);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<SampleMessage> out;
  std::uint32_t seq = 0;
  for (int i = 0; i < steps; ++i) {
    Timestamp t = t0 + static_cast<Timestamp>(i) * 10'000'000;
    {
      auto m = std::make_shared<tinyline_msgs::msg::RawScan>();
      m->header.stamp = stamp_of(t);
      m->header.frame_id = "tiny_laser";
      m->set_index = static_cast<std::uint32_t>(i);
      m->temperature_c = 31.5F + 0.01F * static_cast<float>(i);
      m->pixels = 272;
      m->pulses = {10, 40, 160};
      m->a.resize(3 * 272);
      m->b.resize(3 * 272);
      for (std::size_t k = 0; k < m->a.size(); ++k) {
        m->a[k] = static_cast<std::int16_t>(static_cast<int>(rng() % 60000) - 30000);
        m->b[k] = static_cast<std::int16_t>(static_cast<int>(rng() % 60000) - 30000);
      }
      add(out, "/tiny/raw", m, t++, ++seq);
    }
    {
      auto m = std::make_shared<tinyline_msgs::msg::LineScan>();
      m->header.stamp = stamp_of(t);
      m->header.frame_id = "tiny_laser";
      m->set_index = static_cast<std::uint32_t>(i);
      m->temperature_c = 31.5F;
      for (int k = 0; k < 256; ++k) {
        m->angles.push_back(-0.5F + static_cast<float>(k) / 256.0F);
        const bool valid = (k + i) % 17 != 0;
        m->distance_m.push_back(valid ? 0.05F + std::abs(uf(rng)) / 2.0F : nan);
        m->intensity.push_back(std::abs(uf(rng)) * 100.0F);
        m->reflectance.push_back(std::abs(uf(rng)) * 1e4F);
        m->pulses.push_back(static_cast<std::uint16_t>(10U << (k % 3)));
        m->status.push_back(valid ? 0 : 4);
      }
      add(out, "/tiny/scan", m, t++, ++seq);
    }
    {
      auto m = std::make_shared<sensor_msgs::msg::LaserScan>();
      m->header.stamp = stamp_of(t);
      m->header.frame_id = "laser";
      m->angle_min = -0.5F;
      m->angle_max = 0.5F;
      m->angle_increment = 1.0F / 256.0F;
      m->time_increment = 0.0F;
      m->scan_time = 0.01F;
      m->range_min = 0.05F;
      m->range_max = 2.0F;
      for (int k = 0; k < 256; ++k) {
        m->ranges.push_back(k % 31 == 0 ? std::numeric_limits<float>::infinity() : std::abs(uf(rng)));
        if (i % 2 == 0) m->intensities.push_back(std::abs(uf(rng)));  // sometimes empty
      }
      add(out, "/scan", m, t++, ++seq);
    }
    if (i % 5 == 0) {
      auto m = std::make_shared<sensor_msgs::msg::PointCloud2>();
      m->header.stamp = stamp_of(t);
      m->header.frame_id = "camera";
      m->height = 8;
      m->width = 8;
      tinyline::msg::set_xyzrgb_fields(*m);
      m->point_step = 16;
      m->row_step = 16 * 8;
      m->data.resize(16 * 64);
      for (auto& b : m->data) b = static_cast<std::uint8_t>(rng());
      m->is_dense = i % 10 == 0;
      add(out, "/camera/points", m, t++, ++seq);
    }
    if (i % 3 == 0) {
      auto m = std::make_shared<sensor_msgs::msg::JointState>();
      m->header.stamp = stamp_of(t);
      m->name = {"link1", "link2", "gimbal_roll"};
      m->position = {0.1 * i, -0.2, 3.14159265358979};
      m->velocity = {1e-300, -0.0, 2.5};
      add(out, "/joint_states", m, t++, ++seq);
    }
    if (i % 7 == 0) {
      auto m = std::make_shared<visualization_msgs::msg::MarkerArray>();
      for (int k = 0; k < 2; ++k) {
        visualization_msgs::msg::Marker mk;
        mk.header.stamp = stamp_of(t);
        mk.header.frame_id = "world";
        mk.ns = "tomatoes";
        mk.id = k;
        mk.type = visualization_msgs::msg::Marker::SPHERE_LIST;
        mk.pose.orientation.w = 1.0;
        mk.scale.x = mk.scale.y = mk.scale.z = 0.03;
        mk.color.r = 0.9F;
        mk.color.a = 1.0F;
        mk.lifetime.sec = 1;
        for (int p = 0; p < 3; ++p) {
          geometry_msgs::msg::Point pt;
          pt.x = 0.1 * p;
          pt.y = -0.05 * k;
          pt.z = 0.4;
          mk.points.push_back(pt);
          std_msgs::msg::ColorRGBA c;
          c.g = 0.5F;
          c.a = 1.0F;
          mk.colors.push_back(c);
        }
        mk.text = "Tomate reif \xE2\x9C\x93 \"ok\"";
        mk.mesh_file.filename = "t.stl";
        mk.mesh_file.data = {0, 1, 2, 255};
        visualization_msgs::msg::UVCoordinate uv;
        uv.u = 0.25F;
        uv.v = 0.75F;
        mk.uv_coordinates.push_back(uv);
        m->markers.push_back(mk);
      }
      add(out, "/markers", m, t++, ++seq);
    }
    if (i % 10 == 0) {
      auto m = std::make_shared<diagnostic_msgs::msg::DiagnosticArray>();
      m->header.stamp = stamp_of(t);
      diagnostic_msgs::msg::DiagnosticStatus s;
      s.level = diagnostic_msgs::msg::DiagnosticStatus::WARN;
      s.name = "tiny_laser_driver";
      s.message = "temperature drifting";
      s.hardware_id = "SN-0042";
      diagnostic_msgs::msg::KeyValue kv;
      kv.key = "temperature_c";
      kv.value = "41.2";
      s.values.push_back(kv);
      m->status.push_back(s);
      add(out, "/diagnostics", m, t++, ++seq);
    }
    {
      auto m = std::make_shared<geometry_msgs::msg::PoseStamped>();
      m->header.stamp = stamp_of(t);
      m->header.frame_id = "base";
      m->pose.position.x = 1.0 / 3.0;
      m->pose.orientation.w = std::sqrt(0.5);
      m->pose.orientation.z = std::sqrt(0.5);
      add(out, "/pose", m, t++, ++seq);
    }
    if (i % 4 == 0) {
      auto m = std::make_shared<std_msgs::msg::String>();
      m->data = i % 8 == 0 ? std::string("tab\there \"quoted\" back\\slash\nnew line \xC3\xA9") : std::string();
      add(out, "/chatter", m, t++, ++seq);
    }
    {
      auto m = std::make_shared<rosgraph_msgs::msg::Clock>();
      m->clock = stamp_of(t);
      add(out, "/clock", m, t++, ++seq);
    }
  }
  return out;
}

/// Writes samples through a Ros2Writer.
inline Status write_samples(ros2::Ros2Writer& w, const std::vector<SampleMessage>& samples) {
  std::map<std::string, ChannelId> ids;
  for (const auto& s : samples) {
    auto it = ids.find(s.topic);
    if (it == ids.end()) {
      ChannelId id;
      if (Status st = w.add_topic(s.topic, *s.type, id); !st.ok()) return st;
      it = ids.emplace(s.topic, id).first;
    }
    if (Status st = w.write(it->second, *s.type, s.message.get(), s.log_time, s.publish_time, s.sequence); !st.ok())
      return st;
  }
  return {};
}

/// Indents every line of `text` by `n` spaces.
inline std::string indent(const std::string& text, int n) {
  std::string out;
  bool at_start = true;
  for (char c : text) {
    if (at_start && c != '\n') out.append(static_cast<std::size_t>(n), ' ');
    out.push_back(c);
    at_start = c == '\n';
  }
  return out;
}

/// One YAML document per message: topic, type, times, sequence and the fields
/// (TypeSupport::to_yaml), for the Python side to compare with what it decodes.
inline std::string yaml_doc(const std::string& topic, const msg::TypeSupport& type, const void* message,
                            Timestamp log_time, Timestamp publish_time, std::uint32_t sequence) {
  msg::YamlWriter y;
  type.to_yaml(message, y);
  std::string d = "---\n";
  d += "topic: " + msg::YamlWriter::quote(topic) + "\n";
  d += "type: " + msg::YamlWriter::quote(std::string(type.name)) + "\n";
  d += "log_time: " + std::to_string(log_time) + "\n";
  d += "publish_time: " + std::to_string(publish_time) + "\n";
  d += "sequence: " + std::to_string(sequence) + "\n";
  d += "message:\n" + indent(y.str(), 2);
  return d;
}

inline void write_expected(const std::string& path, const std::vector<SampleMessage>& samples) {
  std::ofstream f(path);
  for (const auto& s : samples)
    f << yaml_doc(s.topic, *s.type, s.message.get(), s.log_time, s.publish_time, s.sequence);
}

}  // namespace tinyline::bag::testing
