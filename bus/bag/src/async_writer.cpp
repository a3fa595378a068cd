// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/async_writer.hpp>

#include <chrono>

#include <fmt/format.h>

namespace tinyline::bag {

AsyncWriter::~AsyncWriter() {
  if (is_open()) (void)close();
}

Status AsyncWriter::open(const std::string& path, AsyncWriterOptions options) {
  auto f = std::make_unique<FileWritable>();
  FileWritableOptions fo;
  fo.keep_partial = true;  // a recording that fails half-way is still worth recovering
  fo.inputs = options.inputs;
  if (Status s = f->open(path, fo); !s.ok()) return s;
  return start(std::move(f), std::move(options));
}

Status AsyncWriter::open(std::unique_ptr<Writable> out, AsyncWriterOptions options) {
  return start(std::move(out), std::move(options));
}

Status AsyncWriter::start(std::unique_ptr<Writable> out, AsyncWriterOptions options) {
  if (is_open()) return {StatusCode::InvalidArgument, fmt::format("{}: already recording", name_)};
  name_ = out ? out->name() : std::string();
  options_ = std::move(options);
  if (Status s = writer_.open(std::move(out), options_.writer); !s.ok()) return s;
  {
    std::lock_guard lk(mu_);
    open_ = true;
    stopping_ = false;
    error_ = {};
    stats_ = {};
    queue_.clear();
  }
  thread_ = std::thread([this] { run(); });
  return {};
}

bool AsyncWriter::is_open() const {
  std::lock_guard lk(mu_);
  return open_;
}

AsyncWriter::TopicId AsyncWriter::add_topic(const std::string& topic, const msg::TypeSupport& type,
                                            std::vector<ros2::QosProfile> offered) {
  std::lock_guard lk(mu_);
  auto e = std::make_unique<TopicEntry>();
  e->name = topic;
  e->type = &type;
  e->offered = std::move(offered);
  topics_.push_back(std::move(e));
  return topics_.size() - 1;
}

std::vector<std::uint8_t> AsyncWriter::take_buffer(TopicId topic) {
  std::lock_guard lk(mu_);
  if (topic >= topics_.size() || topics_[topic]->spare.empty()) return {};
  auto& spare = topics_[topic]->spare;
  std::vector<std::uint8_t> b = std::move(spare.back());
  spare.pop_back();
  recycled_bytes_ -= b.capacity();
  return b;
}

bool AsyncWriter::push(TopicId topic, std::vector<std::uint8_t> cdr, Timestamp log_time, Timestamp publish_time,
                       std::uint32_t sequence) {
  {
    std::lock_guard lk(mu_);
    ++stats_.received;
    const std::uint64_t bytes = cdr.size();
    if (!open_ || stopping_ || !error_.ok() || topic >= topics_.size() ||
        stats_.queued_bytes + bytes > options_.max_queue_bytes) {
      ++stats_.dropped;
      ++stats_.dropped_by_topic[topic < topics_.size() ? topics_[topic]->name : std::string("?")];
      return false;
    }
    stats_.queued_bytes += bytes;
    stats_.max_queued_bytes = std::max(stats_.max_queued_bytes, stats_.queued_bytes);
    queue_.push_back(Item{topic, std::move(cdr), log_time, publish_time, sequence});
  }
  cv_.notify_one();
  return true;
}

bool AsyncWriter::take_batch(std::deque<Item>& batch, std::chrono::steady_clock::time_point wake_at) {
  std::unique_lock lk(mu_);
  cv_.wait_until(lk, wake_at, [&] { return !queue_.empty() || stopping_; });
  batch.swap(queue_);
  return stopping_ && batch.empty();
}

Status AsyncWriter::write_batch(std::deque<Item>& batch, std::uint64_t& written) {
  Status failed = error();
  for (auto& item : batch) {
    if (!failed.ok()) break;
    TopicEntry* t = nullptr;
    {
      std::lock_guard lk(mu_);
      t = topics_[item.topic].get();  // entries are never removed
    }
    if (t->channel == 0) failed = writer_.add_topic(t->name, *t->type, t->channel, t->offered);
    if (failed.ok()) {
      failed = writer_.write_serialized(t->channel, item.cdr, item.log_time, item.publish_time, item.sequence);
    }
    if (failed.ok()) ++written;
  }
  return failed;
}

void AsyncWriter::settle_batch(std::deque<Item>& batch, std::uint64_t written, const Status& failed) {
  std::uint64_t bytes = 0;
  for (const auto& item : batch) bytes += item.cdr.size();
  std::lock_guard lk(mu_);
  stats_.queued_bytes -= bytes;
  stats_.written += written;
  stats_.dropped += batch.size() - written;
  stats_.file = writer_.writer().stats();
  if (!failed.ok() && error_.ok()) error_ = failed;
  for (auto& item : batch) {  // keep some buffers for the callers' next copies
    auto& spare = topics_[item.topic]->spare;
    const std::uint64_t cap = item.cdr.capacity();
    if (cap == 0 || spare.size() >= options_.recycle_per_topic || recycled_bytes_ + cap > options_.max_recycled_bytes) {
      continue;
    }
    item.cdr.clear();
    spare.push_back(std::move(item.cdr));
    recycled_bytes_ += cap;
  }
}

void AsyncWriter::run() {
  using Clock = std::chrono::steady_clock;
  const auto interval = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(options_.flush_interval_s > 0 ? options_.flush_interval_s : 3600.0));
  std::deque<Item> batch;
  auto last_chunk = Clock::now();
  std::uint64_t chunks = 0;
  while (true) {
    const bool stop = take_batch(batch, last_chunk + interval);
    std::uint64_t written = 0;
    Status failed = write_batch(batch, written);
    Writer& w = writer_.writer();
    if (failed.ok() && w.stats().chunks == chunks && options_.flush_interval_s > 0 && w.open_chunk_bytes() > 0 &&
        Clock::now() - last_chunk >= interval) {
      failed = w.flush();  // a quiet period: put what we have on disk
    }
    if (w.stats().chunks != chunks) {
      chunks = w.stats().chunks;
      last_chunk = Clock::now();
      if (options_.on_chunk) options_.on_chunk(w.stats());
    } else if (w.open_chunk_bytes() == 0) {
      last_chunk = Clock::now();  // nothing waiting: restart the quiet-period clock
    }
    settle_batch(batch, written, failed);
    batch.clear();  // frees the rest outside the lock
    if (stop) return;
  }
}

Status AsyncWriter::close(const std::string& metadata_name,
                          const std::function<KeyValueMap(const AsyncWriterStats&)>& metadata) {
  {
    std::lock_guard lk(mu_);
    if (!open_) return error_;
    stopping_ = true;
  }
  cv_.notify_one();
  if (thread_.joinable()) thread_.join();
  Status s = error();
  if (s.ok() && !metadata_name.empty()) {
    s = writer_.writer().write(Metadata{metadata_name, metadata ? metadata(stats()) : KeyValueMap{}});
  }
  Status closed = writer_.close();
  std::lock_guard lk(mu_);
  open_ = false;
  stats_.file = writer_.writer().stats();
  if (error_.ok() && !s.ok()) error_ = s;
  if (error_.ok() && !closed.ok()) error_ = closed;
  return error_;
}

AsyncWriterStats AsyncWriter::stats() const {
  std::lock_guard lk(mu_);
  return stats_;
}

Status AsyncWriter::error() const {
  std::lock_guard lk(mu_);
  return error_;
}

}  // namespace tinyline::bag
