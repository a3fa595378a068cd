// SPDX-License-Identifier: Apache-2.0
// A stream of large clouds whose every byte says which message it belongs
// to, and its checker: what a camera driver and its viewer in two processes
// exchange, made verifiable (shared memory, docs/dds.md).
#include <tinyline/tools/nodes.hpp>

#include <algorithm>
#include <cstring>

#include <fmt/format.h>

#include <tinyline/msg/point_cloud.hpp>

namespace tinyline::tools {

namespace {

using Cloud = sensor_msgs::msg::PointCloud2;

// Word i of cloud `seq`; word 0 is the sequence number itself.
std::uint64_t pattern(std::uint64_t seq, std::uint64_t i) {
  return i == 0 ? seq : (seq * 0x9E3779B97F4A7C15ull) ^ (i * 0xC2B2AE3D27D4EB4Full);
}

std::uint64_t word(const std::vector<std::uint8_t>& d, std::size_t i) {
  std::uint64_t w = 0;
  std::memcpy(&w, d.data() + i * 8, 8);
  return w;
}

class CloudSource : public bus::Node {
 public:
  explicit CloudSource(bus::NodeOptions o) : Node(std::move(o)) {
    width_ = declare_parameter("width", 640, "points per row", bus::ParamConstraints::range(1, 100000));
    height_ = declare_parameter("height", 480, "rows", bus::ParamConstraints::range(1, 100000));
    point_step_ = declare_parameter("point_step", 32, "bytes per point (XYZRGB padded: 32)",
                                    bus::ParamConstraints::range(16, 1024));
    const double rate =
        declare_parameter("rate_hz", 30.0, "publish rate [Hz]", bus::ParamConstraints::range(0.001, 10000.0));
    limit_ = declare_parameter("count", 0, "clouds to publish, then stay quiet (0: no limit)",
                               bus::ParamConstraints::at_least(0));
    const int depth = declare_parameter("depth", 4, "queue depth", bus::ParamConstraints::range(1, 256));
    pub_ = create_publisher<Cloud>("output", bus::QoS::keep_last(static_cast<std::size_t>(depth)));
    timer_ = create_timer(bus::from_seconds(1.0 / rate), [this] { publish_next(); });
  }

 private:
  void publish_next() {
    if (limit_ > 0 && seq_ >= static_cast<std::uint64_t>(limit_)) {
      timer_->cancel();
      return;
    }
    auto c = std::make_unique<Cloud>();
    c->header.frame_id = "camera";
    c->width = static_cast<std::uint32_t>(width_);
    c->height = static_cast<std::uint32_t>(height_);
    c->point_step = static_cast<std::uint32_t>(point_step_);
    c->row_step = c->point_step * c->width;
    msg::set_xyzrgb_fields(*c);
    c->data.resize(static_cast<std::size_t>(c->row_step) * c->height);
    const std::uint64_t seq = ++seq_;
    for (std::size_t i = 0; i < c->data.size() / 8; ++i) {
      const std::uint64_t w = pattern(seq, i);
      std::memcpy(c->data.data() + i * 8, &w, 8);
    }
    c->header.stamp = now().to_msg();  // last: the latency is the transport's
    pub_->publish(std::move(c));
  }

  int width_ = 0, height_ = 0, point_step_ = 0, limit_ = 0;
  std::uint64_t seq_ = 0;
  std::shared_ptr<bus::Publisher<Cloud>> pub_;
  std::shared_ptr<bus::Timer> timer_;
};

class CloudCheck : public bus::Node {
 public:
  explicit CloudCheck(bus::NodeOptions o) : Node(std::move(o)) {
    expect_ = declare_parameter("expect", 0,
                                "clouds the source publishes (0: unknown; then losses at the end go "
                                "uncounted)",
                                bus::ParamConstraints::at_least(0));
    report_every_ = declare_parameter("report_every", 0, "log a progress line every N clouds (0: only at the end)",
                                      bus::ParamConstraints::at_least(0));
    const int depth = declare_parameter("depth", 4, "queue depth", bus::ParamConstraints::range(1, 256));
    sub_ = create_subscription<Cloud>("input", bus::QoS::keep_last(static_cast<std::size_t>(depth)),
                                      [this](const std::shared_ptr<const Cloud>& c) { check(*c); });
  }

  void on_stop() override { logger().info("{}", summary()); }

 private:
  void check(const Cloud& c) {
    const double latency_ms = (now() - bus::Time::from_msg(c.header.stamp)).count() * 1e-6;
    const bool sized = c.data.size() == static_cast<std::size_t>(c.row_step) * c.height && c.data.size() >= 8;
    const std::uint64_t seq = sized ? word(c.data, 0) : 0;
    bool intact = sized;
    for (std::size_t i = 1; intact && i < c.data.size() / 8; ++i) intact = word(c.data, i) == pattern(seq, i);
    ++received_;
    if (!intact) {
      ++corrupt_;
      return;
    }
    if (seq > last_seq_) missing_ += seq - last_seq_ - 1;
    last_seq_ = std::max(last_seq_, seq);
    latencies_ms_.push_back(latency_ms);
    if (report_every_ > 0 && received_ % static_cast<std::uint64_t>(report_every_) == 0) {
      logger().info("{} clouds so far", received_);
    }
  }

  std::string summary() {
    std::uint64_t missing = missing_;
    if (expect_ > 0 && last_seq_ < static_cast<std::uint64_t>(expect_)) missing += expect_ - last_seq_;
    std::string s = fmt::format("clouds: {} received, {} intact, {} corrupt, {} missing", received_,
                                received_ - corrupt_, corrupt_, missing);
    if (latencies_ms_.empty()) return s;
    std::sort(latencies_ms_.begin(), latencies_ms_.end());
    auto at = [&](double q) { return latencies_ms_[static_cast<std::size_t>(q * (latencies_ms_.size() - 1))]; };
    return s + fmt::format("; latency p50 {:.2f} ms, p99 {:.2f} ms, max {:.2f} ms", at(0.5), at(0.99),
                           latencies_ms_.back());
  }

  int expect_ = 0, report_every_ = 0;
  std::uint64_t received_ = 0, corrupt_ = 0, missing_ = 0, last_seq_ = 0;
  std::vector<double> latencies_ms_;
  std::shared_ptr<bus::Subscription<Cloud>> sub_;
};

}  // namespace

void register_cloud_stream(bus::NodeRegistry& r) {
  r.add<CloudSource>("tinyline", "cloud_source",
                     "publishes XYZRGB clouds on 'output' whose bytes encode their sequence number");
  r.add<CloudCheck>("tinyline", "cloud_check",
                    "checks every cloud of a cloud_source on 'input': intact, none missing, latency");
}

}  // namespace tinyline::tools
