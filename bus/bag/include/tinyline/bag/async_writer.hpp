// SPDX-License-Identifier: Apache-2.0
// A ROS 2 bag writer on its own thread: callers hand over serialized
// messages and return at once; compression and file I/O happen on the writer
// thread. The queue between them has a byte budget: a message that would
// overflow it is refused, counted per topic and reported, never lost
// silently. The recorder node and `tinyline bag record` are built on it.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <tinyline/bag/ros2.hpp>
#include <tinyline/bag/writer.hpp>

namespace tinyline::bag {

struct AsyncWriterOptions {
  WriterOptions writer;
  /// The recording command's input files (its launch file): the bag never replaces one.
  std::vector<std::string> inputs;
  /// Serialized bytes allowed to wait for the writer thread; past this a
  /// message is refused (and counted) instead of growing memory without bound.
  std::uint64_t max_queue_bytes = 256ULL << 20;
  /// Close the open chunk when none was closed for this long [s], so the file
  /// on disk never lags far behind (0: only when the chunk is full).
  double flush_interval_s = 1.0;
  /// Written messages' buffers kept per topic for take_buffer(), so steady
  /// traffic reuses memory instead of having the kernel map and zero fresh
  /// pages for every copy (a 4.9 MB point cloud is 1,200 page faults).
  std::size_t recycle_per_topic = 4;
  /// Bound on the bytes (capacity) kept for reuse over all topics.
  std::uint64_t max_recycled_bytes = 64ULL << 20;
  /// Called on the writer thread after each chunk reached the file.
  std::function<void(const WriterStats&)> on_chunk;
};

struct AsyncWriterStats {
  std::uint64_t received = 0;          ///< messages handed to push()
  std::uint64_t written = 0;           ///< messages in the file
  std::uint64_t dropped = 0;           ///< refused: queue full, or the file failed
  std::uint64_t queued_bytes = 0;      ///< waiting now
  std::uint64_t max_queued_bytes = 0;  ///< high-water mark
  std::map<std::string, std::uint64_t> dropped_by_topic;
  WriterStats file;
};

class AsyncWriter {
 public:
  using TopicId = std::size_t;

  AsyncWriter() = default;
  /// Closes (draining the queue) if still open.
  ~AsyncWriter();
  AsyncWriter(const AsyncWriter&) = delete;
  AsyncWriter& operator=(const AsyncWriter&) = delete;

  Status open(const std::string& path, AsyncWriterOptions options = {});
  Status open(std::unique_ptr<Writable> out, AsyncWriterOptions options = {});
  bool is_open() const;

  /// Declares a topic (thread-safe; the channel is written with its first message).
  TopicId add_topic(const std::string& topic, const msg::TypeSupport& type,
                    std::vector<ros2::QosProfile> offered = {ros2::QosProfile{}});

  /// An empty buffer to serialize `topic`'s next message into: one a written
  /// message of that topic left behind (capacity kept) when there is one,
  /// else a new one. Thread-safe.
  [[nodiscard]] std::vector<std::uint8_t> take_buffer(TopicId topic);

  /// Queues one message (encapsulated CDR). Returns false when it was refused:
  /// the queue is over its budget, the file failed, or the writer is closed.
  /// Never waits for I/O.
  bool push(TopicId topic, std::vector<std::uint8_t> cdr, Timestamp log_time, Timestamp publish_time,
            std::uint32_t sequence);

  /// Drains the queue, adds a Metadata record named `metadata_name` with what
  /// `metadata` returns for the final statistics (if a name is given),
  /// finishes the file. Returns the first error.
  Status close(const std::string& metadata_name = {},
               const std::function<KeyValueMap(const AsyncWriterStats&)>& metadata = {});

  AsyncWriterStats stats() const;
  /// The first write error (ok while the file is healthy).
  Status error() const;
  const std::string& name() const { return name_; }

 private:
  struct Item {
    TopicId topic = 0;
    std::vector<std::uint8_t> cdr;
    Timestamp log_time = 0;
    Timestamp publish_time = 0;
    std::uint32_t sequence = 0;
  };
  struct TopicEntry {
    std::string name;
    const msg::TypeSupport* type = nullptr;
    std::vector<ros2::QosProfile> offered;
    ChannelId channel = 0;                         // writer thread only
    std::vector<std::vector<std::uint8_t>> spare;  // written buffers for take_buffer (under mu_)
  };

  Status start(std::unique_ptr<Writable> out, AsyncWriterOptions options);
  void run();
  /// Waits for messages (or `wake_at`) and takes all queued; true when stopping and nothing is left.
  bool take_batch(std::deque<Item>& batch, std::chrono::steady_clock::time_point wake_at);
  /// Writes the batch until an error (the file's first error stays); counts what reached the writer.
  Status write_batch(std::deque<Item>& batch, std::uint64_t& written);
  /// Books the batch (written, dropped, queue bytes) and keeps some buffers for reuse.
  void settle_batch(std::deque<Item>& batch, std::uint64_t written, const Status& failed);

  AsyncWriterOptions options_;
  std::string name_;
  ros2::Ros2Writer writer_;  // writer thread only (after open)
  std::thread thread_;

  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<Item> queue_;
  std::vector<std::unique_ptr<TopicEntry>> topics_;
  bool open_ = false;
  bool stopping_ = false;
  Status error_;
  AsyncWriterStats stats_;
  std::uint64_t recycled_bytes_ = 0;  // capacity held in the topics' spare buffers
};

}  // namespace tinyline::bag
