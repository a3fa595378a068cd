// The recorder node (`bag/recorder` in launch files): one reliable
// subscription per topic (every topic of the graph by default, including
// topics created later), each message serialized on arrival and handed to an
// AsyncWriter, whose thread compresses and writes. Publishers never wait on
// the disk; a message the queue cannot take is counted per topic, logged and
// written into the bag's "tinyline_recorder" metadata record, never lost
// silently. The file is opened in on_start() and finished in on_stop().
#pragma once

#include <atomic>
#include <memory>
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
  /// Topics to record; empty: all topics.
  std::vector<std::string> topics;
  /// Topics never recorded (when recording all).
  std::vector<std::string> exclude;
  /// Queue of each topic's reliable subscription [messages].
  std::size_t queue_depth = 1000;
  AsyncWriterOptions writer;
};

struct RecorderStats {
  std::uint64_t received = 0;              ///< messages taken from subscriptions
  std::uint64_t written = 0;               ///< messages in the file
  std::uint64_t dropped = 0;               ///< refused by a full queue or a failed file (reported)
  std::uint64_t subscription_timeouts = 0; ///< publishers that timed out on a full recorder subscription
  std::uint64_t file_bytes = 0;
  std::size_t topics = 0;
};

class Recorder : public bus::Node {
 public:
  /// Built from parameters (path, topics, exclude, compression, compression_level,
  /// chunk_size_kb, queue_depth, max_queue_mb, flush_interval_s), defaults from RecorderOptions.
  explicit Recorder(bus::NodeOptions options);
  /// Defaults from `defaults` (parameters still override them).
  Recorder(bus::NodeOptions options, RecorderOptions defaults);
  /// Writes to `sink` instead of a file (tests).
  Recorder(bus::NodeOptions options, RecorderOptions defaults, std::unique_ptr<Writable> sink);
  ~Recorder() override;

  void on_start() override;
  void on_stop() override;

  /// Starts recording now (on_start() calls it). Throws BagError if the file cannot be created.
  void start();
  /// Stops, drains and finishes the file; returns its status. Idempotent.
  Status stop();

  RecorderStats stats() const;
  const std::string& path() const { return opts_.path; }
  bool recording() const { return recording_.load(); }

 private:
  void subscribe(const std::shared_ptr<bus::Topic>& topic);
  void on_message(AsyncWriter::TopicId id, const std::string& topic, const std::shared_ptr<const void>& msg,
                  const msg::TypeSupport& type, const bus::MessageInfo& info);

  RecorderOptions opts_;
  std::unique_ptr<Writable> sink_;
  AsyncWriter writer_;
  std::atomic<bool> recording_{false};
  bool stopped_ = false;
  int listener_ = 0;
  mutable std::mutex mu_;
  std::set<std::string> subscribed_;
  std::vector<std::shared_ptr<bus::GenericSubscription>> subs_;
  std::atomic<std::uint64_t> drops_logged_{0};
  Status final_;
};

}  // namespace tinyline::bag
