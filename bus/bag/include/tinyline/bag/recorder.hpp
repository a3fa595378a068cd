// SPDX-License-Identifier: Apache-2.0
// The recorder node (`bag/recorder` in launch files): one reliable
// subscription per topic (every topic of the graph by default, including
// topics created later), each message serialized on arrival and handed to an
// AsyncWriter, whose thread compresses and writes. Publishers never wait on
// the disk. A message the recorder cannot take (its subscription queue stayed
// full, the write queue is over its budget, the file failed, the executor
// stopped first) is dropped whole, counted per topic, logged and written into
// the bag's "tinyline_recorder" metadata record, never lost silently. The
// file is opened in on_start() as <path>.part, renamed to the path when
// on_stop() finishes it; a recording that fails keeps its .part for
// `tinyline bag recover`.
#pragma once

#include <atomic>
#include <map>
#include <memory>
#include <optional>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include <tinyline/bag/async_writer.hpp>
#include <tinyline/bus/node.hpp>

namespace tinyline::bag {

struct RecorderOptions {
  /// Output file; empty: "tinyline_<YYYYmmdd_HHMMSS>.mcap" in the working directory.
  std::string path;
  /// Topics to record; empty: all topics. Relative names resolve against the
  /// recorder's namespace, as every ROS name does ("demo/raw" -> "/demo/raw").
  std::vector<std::string> topics;
  /// Topics never recorded (when recording all); resolved the same way.
  std::vector<std::string> exclude;
  /// Queue of each topic's reliable subscription [messages].
  std::size_t queue_depth = 1000;
  AsyncWriterOptions writer;
};

struct RecorderStats {
  std::uint64_t received = 0;               ///< messages taken from subscriptions
  std::uint64_t written = 0;                ///< messages in the file
  std::uint64_t dropped = 0;                ///< every message not in the file, whatever the cause (reported)
  std::uint64_t subscription_timeouts = 0;  ///< of those: publishers that found a recorder queue full
  std::uint64_t lost_upstream = 0;          ///< of those: lost by the transport before they reached the process
  std::uint64_t file_bytes = 0;
  std::size_t topics = 0;
  std::map<std::string, std::uint64_t> dropped_by_topic;  ///< `dropped`, per topic
};

class Recorder : public bus::Node {
 public:
  /// Built from parameters (RecorderOptions' table, <tinyline/bag/param_tables.hpp>),
  /// defaults from RecorderOptions.
  explicit Recorder(bus::NodeOptions options);
  /// Defaults from `defaults` (parameters still override them).
  Recorder(bus::NodeOptions options, RecorderOptions defaults);
  /// Writes to `sink` instead of a file (tests).
  Recorder(bus::NodeOptions options, RecorderOptions defaults, std::unique_ptr<Writable> sink);
  ~Recorder() override;

  void on_start() override;
  /// Stops (see stop()); throws BagError if the file could not be finished.
  void on_stop() override;

  /// Starts recording now (on_start() calls it). Throws BagError if the file cannot be created.
  void start();
  /// Stops: records what its queues still hold, counts anything left as
  /// dropped, finishes the file and puts it in place; returns its status.
  /// Idempotent.
  Status stop();

  RecorderStats stats() const;
  const std::string& path() const { return opts_.path; }
  /// The settings as the parameters gave them (topic names resolved).
  const RecorderOptions& options() const { return opts_; }
  bool recording() const { return recording_.load(); }

 private:
  /// One recorded topic. Counts are atomics: callbacks run on executor threads.
  struct TopicState {
    std::string name;
    std::shared_ptr<bus::GenericSubscription> sub;
    std::shared_ptr<bus::Topic> topic;
    std::uint64_t lost_before = 0;             ///< the topic's transport losses when recording began on it
    std::optional<AsyncWriter::TopicId> id;    ///< declared with the first message
    std::atomic<std::uint64_t> after_stop{0};  ///< callbacks that came after recording ended
    std::atomic<std::uint64_t> discarded{0};   ///< left in the queue when it was cancelled
  };

  void subscribe(const std::shared_ptr<bus::Topic>& topic);
  void on_message(TopicState& t, const std::shared_ptr<const void>& msg, const msg::TypeSupport& type,
                  const bus::MessageInfo& info);
  /// Runs the callbacks for what the subscription queues hold (the executor may have stopped).
  void drain();
  /// Ends every subscription; what they still hold counts as discarded.
  void cancel_subscriptions();
  KeyValueMap metadata(const AsyncWriterStats& ws) const;
  void report(const Status& final_status) const;

  RecorderOptions opts_;
  std::unique_ptr<Writable> sink_;
  AsyncWriter writer_;
  std::atomic<bool> recording_{false};
  bool stopped_ = false;
  int listener_ = 0;
  mutable std::mutex mu_;
  std::set<std::string> subscribed_;
  std::vector<std::unique_ptr<TopicState>> topics_;  // never shrinks: callbacks hold pointers
  std::atomic<std::uint64_t> drops_logged_{0};
  Status final_;
};

}  // namespace tinyline::bag
