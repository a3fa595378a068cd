// SPDX-License-Identifier: Apache-2.0
// PointCloud2 clouds read in place: a subscriber that opts in gets each
// cloud's fields decoded and its `data` as a view into the sample DDS
// received, which for a sender on this machine over shared memory is the
// iceoryx chunk the sender serialized into: no deserializing copy of the
// payload (docs/dds.md, "Shared memory").
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <tinyline/dds/participant.hpp>
#include <tinyline/msg/sensor_msgs/point_field.hpp>
#include <tinyline/msg/std_msgs/header.hpp>

namespace tinyline::dds {

/// A sensor_msgs/PointCloud2 whose `data` stays in the received sample. The
/// sample (and its shared-memory chunk) is held while the view lives: drop
/// the view to give the chunk back.
struct PointCloud2View {
  std_msgs::msg::Header header;
  std::uint32_t height = 0;
  std::uint32_t width = 0;
  std::vector<sensor_msgs::msg::PointField> fields;
  bool is_bigendian = false;
  std::uint32_t point_step = 0;
  std::uint32_t row_step = 0;
  std::span<const std::uint8_t> data;  ///< in the sample; valid while this view lives
  bool is_dense = false;
  bool in_shared_memory = false;       ///< `data` lies in a shared-memory chunk
  std::shared_ptr<const void> sample;  ///< what keeps `data` alive
};

/// A DDS reader of a PointCloud2 topic that hands each cloud over as a
/// PointCloud2View, beside (not through) the bus: for a subscriber that
/// reads a large cloud once and does not need to own it. Keep-last `depth`,
/// reliable, volatile: the QoS shared memory serves. The callback runs on
/// DDS's receive thread, one cloud at a time; it may keep views as long as
/// it likes (the reader lives until the last view goes). Samples that do
/// not decode as PointCloud2 are counted and dropped. Own-process writes are
/// not filtered out.
class CloudViewSubscription {
 public:
  using Callback = std::function<void(std::shared_ptr<const PointCloud2View>)>;
  /// Throws DdsError if the reader cannot be created. `topic` is a tinyline
  /// topic name ("/camera/points").
  CloudViewSubscription(Participant& participant, const std::string& topic, int depth, Callback callback);
  ~CloudViewSubscription();  ///< no callback runs after it returns
  CloudViewSubscription(const CloudViewSubscription&) = delete;
  CloudViewSubscription& operator=(const CloudViewSubscription&) = delete;

  /// Shared memory serves this reader (Cyclone's iceoryx transport is on and
  /// the QoS allows it).
  bool shared_memory() const;
  std::uint64_t received() const;
  std::uint64_t decode_errors() const;

  struct State;  ///< shared with the listener and every view

 private:
  std::shared_ptr<State> state_;
};

}  // namespace tinyline::dds
