// SPDX-License-Identifier: Apache-2.0
// The player node (`bag/player`): publishes a bag's messages on their topics,
// decoded with each type's TypeSupport, paced by their log times (at a chosen
// rate), optionally looping, from an offset, for chosen topics. With `clock`
// it publishes rosgraph_msgs/Clock on /clock and, when its context runs on
// sim time, drives that clock: timers of nodes in the same process then
// follow the bag. Playback runs on its own thread from on_start().
#pragma once

#include <atomic>
#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <tinyline/bag/reader.hpp>
#include <tinyline/bus/node.hpp>
#include <tinyline/msg/rosgraph_msgs/clock.hpp>

namespace tinyline::bag {

struct PlayerOptions {
  std::string path;                 ///< the bag (required)
  double rate = 1.0;                ///< playback speed, x real time; 0: as fast as possible
  bool loop = false;                ///< start over at the end
  std::vector<std::string> topics;  ///< topics to play; empty: every topic of a known type
  double start_offset_s = 0.0;      ///< skip this much of the bag's beginning [s]
  bool clock = false;               ///< publish /clock (and drive this context's sim clock)
  double clock_hz = 100.0;          ///< /clock rate between messages [Hz]
};

struct PlayerStats {
  std::uint64_t published = 0;  ///< messages handed to the bus
  std::uint64_t failed = 0;     ///< messages that did not decode, or that a subscriber refused
  std::uint64_t loops = 0;      ///< completed passes through the bag
  Timestamp bag_start = 0;      ///< first message time [ns]
  Timestamp bag_end = 0;        ///< last message time [ns]
  Timestamp position = 0;       ///< log time of the last message published [ns]
  bool finished = false;        ///< the last pass ended (or playback failed)
  Status status;                ///< why playback ended early, if it did
};

class Player : public bus::Node {
 public:
  /// Parameters: path, rate, loop, topics, start_offset_s, clock, clock_hz (defaults from PlayerOptions).
  explicit Player(bus::NodeOptions options);
  Player(bus::NodeOptions options, PlayerOptions defaults);
  ~Player() override;

  /// Opens the bag, creates the publishers and starts the playback thread.
  /// Throws BagError if the bag cannot be opened.
  void on_start() override;
  void on_stop() override;

  /// Stops playback and joins the thread. Idempotent.
  void stop();
  /// Waits until playback finished or `timeout` passed; true if finished.
  bool wait_finished(std::chrono::nanoseconds timeout);
  PlayerStats stats() const;
  const PlayerOptions& options() const { return opts_; }

 private:
  struct Out {
    std::shared_ptr<bus::GenericPublisher> pub;
    const msg::TypeSupport* type = nullptr;
  };
  void open();
  void run();
  bool wait_until(std::chrono::steady_clock::time_point t);  // false when stopped
  void publish_clock(Timestamp t);

  PlayerOptions opts_;
  Reader reader_;
  std::map<ChannelId, Out> outs_;
  std::vector<std::string> play_topics_;
  std::shared_ptr<bus::Publisher<rosgraph_msgs::msg::Clock>> clock_pub_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  bool opened_ = false;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  PlayerStats stats_;
};

}  // namespace tinyline::bag
