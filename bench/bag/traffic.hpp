// SPDX-License-Identifier: Apache-2.0
// Realistic recording traffic for the bag benchmarks, serialized once:
//   /tiny/raw       tinyline_msgs/RawScan, 272 px x 5 read-outs (5.5 KB) at 36 Hz
//   /tiny/scan      tinyline_msgs/LineScan, 256 px (4.9 KB) at 100 Hz
//   /camera/points  sensor_msgs/PointCloud2, VGA XYZRGB (4.9 MB) at 10 Hz
//   /pose           geometry_msgs/PoseStamped at 100 Hz
//   /joint_states   sensor_msgs/JointState (6 joints) at 50 Hz
// Values follow the physics roughly so compressors see realistic entropy:
// capacitor charges grow with the pulse count and carry ADC noise; ranges are
// a smooth scene plus noise, NaN where invalid; the cloud is a depth image of
// a tilted panel with spheres (tomatoes), depth noise growing with range,
// missing depth at the sphere edges, colours with sensor noise.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <tinyline/msg/geometry_msgs/pose_stamped.hpp>
#include <tinyline/msg/point_cloud.hpp>
#include <tinyline/msg/sensor_msgs/joint_state.hpp>
#include <tinyline/msg/sensor_msgs/point_cloud2.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>
#include <tinyline/msg/tinyline_msgs/raw_scan.hpp>

namespace tinyline::bench {

struct TrafficMessage {
  int topic = 0;  ///< index into kTopics
  std::int64_t t_ns = 0;
  std::vector<std::uint8_t> cdr;
};

struct TopicSpec {
  const char* name;
  const msg::TypeSupport& (*type)();
};

inline const TopicSpec kTopics[] = {
    {"/tiny/raw", []() -> const msg::TypeSupport& { return msg::type_support<tinyline_msgs::msg::RawScan>(); }},
    {"/tiny/scan", []() -> const msg::TypeSupport& { return msg::type_support<tinyline_msgs::msg::LineScan>(); }},
    {"/camera/points", []() -> const msg::TypeSupport& { return msg::type_support<sensor_msgs::msg::PointCloud2>(); }},
    {"/pose", []() -> const msg::TypeSupport& { return msg::type_support<geometry_msgs::msg::PoseStamped>(); }},
    {"/joint_states", []() -> const msg::TypeSupport& { return msg::type_support<sensor_msgs::msg::JointState>(); }},
};

inline builtin_interfaces::msg::Time stamp(std::int64_t t) {
  builtin_interfaces::msg::Time s;
  s.sec = static_cast<std::int32_t>(t / 1'000'000'000);
  s.nanosec = static_cast<std::uint32_t>(t % 1'000'000'000);
  return s;
}

inline std::vector<std::uint8_t> raw_scan(std::mt19937& rng, std::int64_t t, std::uint32_t i) {
  tinyline_msgs::msg::RawScan m;
  m.header.stamp = stamp(t);
  m.header.frame_id = "tiny_laser";
  m.set_index = i;
  m.temperature_c = 35.0F + 0.001F * static_cast<float>(i);
  m.pixels = 272;
  m.pulses = {10, 40, 160, 640, 2560};
  std::normal_distribution<float> adc(0.0F, 6.0F);
  m.a.resize(5 * 272);
  m.b.resize(5 * 272);
  for (int r = 0; r < 5; ++r) {
    for (int p = 0; p < 272; ++p) {
      const float range = 0.3F + 0.2F * std::sin(static_cast<float>(p) * 0.02F + static_cast<float>(i) * 0.01F);
      const float ratio = 0.2F + 0.5F * range;  // the gated ratio grows with range
      const float signal = static_cast<float>(m.pulses[static_cast<std::size_t>(r)]) * 12.0F / (range * range);
      const auto clampi = [](float v) { return static_cast<std::int16_t>(std::clamp(v, -32768.0F, 32767.0F)); };
      m.a[static_cast<std::size_t>(r * 272 + p)] = clampi(signal * (1 - ratio) + adc(rng));
      m.b[static_cast<std::size_t>(r * 272 + p)] = clampi(signal * ratio + adc(rng));
    }
  }
  return msg::serialize(m);
}

inline std::vector<std::uint8_t> line_scan(std::mt19937& rng, std::int64_t t, std::uint32_t i) {
  tinyline_msgs::msg::LineScan m;
  m.header.stamp = stamp(t);
  m.header.frame_id = "tiny_laser";
  m.set_index = i;
  m.temperature_c = 35.0F;
  std::normal_distribution<float> noise(0.0F, 0.004F);
  for (int p = 0; p < 256; ++p) {
    const float angle = -0.6F + 1.2F * static_cast<float>(p) / 255.0F;
    const float range = 0.3F + 0.2F * std::sin(static_cast<float>(p) * 0.02F + static_cast<float>(i) * 0.01F);
    const bool valid = (p * 7 + static_cast<int>(i)) % 41 != 0;
    m.angles.push_back(angle);
    m.distance_m.push_back(valid ? range + noise(rng) : std::numeric_limits<float>::quiet_NaN());
    m.intensity.push_back(120.0F / (range * range) + 40.0F * noise(rng));
    m.reflectance.push_back(3000.0F + 1000.0F * noise(rng));
    m.pulses.push_back(valid ? 640 : 2560);
    m.status.push_back(valid ? 0 : 2);
  }
  return msg::serialize(m);
}

inline std::vector<std::uint8_t> vga_cloud(std::mt19937& rng, std::int64_t t) {
  sensor_msgs::msg::PointCloud2 m;
  m.header.stamp = stamp(t);
  m.header.frame_id = "camera";
  m.height = 480;
  m.width = 640;
  tinyline::msg::set_xyzrgb_fields(m);
  m.point_step = 16;
  m.row_step = 16 * 640;
  m.is_dense = false;
  m.data.resize(static_cast<std::size_t>(16) * 640 * 480);
  std::normal_distribution<float> unit(0.0F, 1.0F);
  const float fx = 525.0F, cx = 319.5F, cy = 239.5F;
  struct Sphere {
    float x, y, z, r;
  };
  const Sphere spheres[] = {{-0.12F, 0.02F, 0.75F, 0.035F}, {0.0F, 0.06F, 0.72F, 0.032F}, {0.1F, -0.03F, 0.78F, 0.03F}};
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int v = 0; v < 480; ++v) {
    for (int u = 0; u < 640; ++u) {
      const float dx = (static_cast<float>(u) - cx) / fx, dy = (static_cast<float>(v) - cy) / fx;
      float z = 1.1F + 0.25F * dy;  // a tilted panel behind the truss
      std::uint8_t r = 110, g = 110, b = 115;
      bool edge = false;
      for (const auto& s : spheres) {
        // Ray (dx, dy, 1) * z against the sphere.
        const float a = dx * dx + dy * dy + 1, bb = -2 * (dx * s.x + dy * s.y + s.z);
        const float c = s.x * s.x + s.y * s.y + s.z * s.z - s.r * s.r;
        const float disc = bb * bb - 4 * a * c;
        if (disc >= 0) {
          const float hit = (-bb - std::sqrt(disc)) / (2 * a);
          if (hit > 0 && hit < z) {
            z = hit;
            r = 200;
            g = 30;
            b = 25;
            edge = disc < 0.0004F * a;  // grazing rays: structured light loses them
          }
        }
      }
      const float sigma = 0.0012F * z * z;  // structured-light depth noise grows with range squared
      const float zn = z + sigma * unit(rng);
      float px = dx * zn, py = dy * zn, pz = zn;
      if (edge) px = py = pz = nan;
      auto c8 = [&](std::uint8_t base) {
        return static_cast<std::uint8_t>(std::clamp(static_cast<float>(base) + 4.0F * unit(rng), 0.0F, 255.0F));
      };
      const std::uint32_t rgb = (std::uint32_t{c8(r)} << 16) | (std::uint32_t{c8(g)} << 8) | c8(b);
      float rgbf;
      std::memcpy(&rgbf, &rgb, 4);
      std::uint8_t* p = m.data.data() + (static_cast<std::size_t>(v) * 640 + static_cast<std::size_t>(u)) * 16;
      std::memcpy(p, &px, 4);
      std::memcpy(p + 4, &py, 4);
      std::memcpy(p + 8, &pz, 4);
      std::memcpy(p + 12, &rgbf, 4);
    }
  }
  (void)t;
  return msg::serialize(m);
}

inline std::vector<std::uint8_t> pose(std::int64_t t, std::uint32_t i) {
  geometry_msgs::msg::PoseStamped m;
  m.header.stamp = stamp(t);
  m.header.frame_id = "world";
  m.pose.position.x = 0.5 + 0.01 * std::sin(i * 0.1);
  m.pose.orientation.w = 1.0;
  return msg::serialize(m);
}

inline std::vector<std::uint8_t> joints(std::int64_t t, std::uint32_t i) {
  sensor_msgs::msg::JointState m;
  m.header.stamp = stamp(t);
  m.name = {"link1", "link2", "link3", "link4", "gimbal_roll", "gimbal_pitch"};
  for (int k = 0; k < 6; ++k) {
    m.position.push_back(0.3 * std::sin(i * 0.05 + k));
    m.velocity.push_back(0.1 * std::cos(i * 0.05 + k));
  }
  return msg::serialize(m);
}

/// `seconds` of traffic, in time order. `with_cloud` adds the VGA cloud topic.
inline std::vector<TrafficMessage> make_traffic(double seconds, bool with_cloud, bool with_extra = true) {
  std::mt19937 rng(42);
  std::vector<TrafficMessage> out;
  const std::int64_t t0 = 1'700'000'000'000'000'000LL;
  const auto end = static_cast<std::int64_t>(seconds * 1e9);
  struct Rate {
    int topic;
    double hz;
  };
  std::vector<Rate> rates = {{0, 36.0}, {1, 100.0}};
  if (with_cloud) rates.push_back({2, 10.0});
  if (with_extra) {
    rates.push_back({3, 100.0});
    rates.push_back({4, 50.0});
  }
  std::vector<std::vector<std::uint8_t>> clouds;
  for (const auto& r : rates) {
    const auto period = static_cast<std::int64_t>(1e9 / r.hz);
    std::uint32_t i = 0;
    for (std::int64_t t = period / 7; t < end; t += period, ++i) {
      TrafficMessage m;
      m.topic = r.topic;
      m.t_ns = t0 + t;
      switch (r.topic) {
        case 0: m.cdr = raw_scan(rng, m.t_ns, i); break;
        case 1: m.cdr = line_scan(rng, m.t_ns, i); break;
        case 2: {
          // Ten distinct clouds, then repeats: each cloud fills a chunk of its
          // own, so repeats compress no better, and generating costs less.
          if (clouds.size() < 10) clouds.push_back(vga_cloud(rng, m.t_ns));
          m.cdr = clouds[i % clouds.size()];
          break;
        }
        case 3: m.cdr = pose(m.t_ns, i); break;
        default: m.cdr = joints(m.t_ns, i); break;
      }
      out.push_back(std::move(m));
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.t_ns < b.t_ns; });
  return out;
}

}  // namespace tinyline::bench
