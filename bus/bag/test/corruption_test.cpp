// SPDX-License-Identifier: Apache-2.0
// Damaged files: truncation at every length, bad magic, wrong CRCs, lengths
// past the end, random byte flips, and a writer killed with SIGKILL. Each
// gives a clear error or a recovered partial read; never a crash, and never an
// allocation out of proportion to the file (checked by counting the largest
// single allocation while reading).
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>

#include <tinyline/bag/crc32.hpp>
#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/recover.hpp>
#include <tinyline/bag/ros2.hpp>
#include <tinyline/msg/std_msgs/string.hpp>

#include "alloc_tracker.hpp"

namespace tinyline::bag {
namespace {

using Bytes = std::vector<std::uint8_t>;

using testing::Tracking;

// A bag of `n` String messages "m<i>" on two topics, with small chunks.
Bytes make_bag(int n, WriterOptions opt = {}, std::vector<std::uint64_t>* chunk_ends = nullptr) {
  ros2::Ros2Writer w;
  auto sink = std::make_unique<MemoryWritable>();
  auto* mem = sink.get();
  if (opt.chunk_size_bytes == WriterOptions{}.chunk_size_bytes) opt.chunk_size_bytes = 1024;
  EXPECT_TRUE(w.open(std::move(sink), opt).ok());
  ChannelId a, b;
  EXPECT_TRUE(w.add_topic("/a", msg::type_support<std_msgs::msg::String>(), a).ok());
  EXPECT_TRUE(w.add_topic("/b", msg::type_support<std_msgs::msg::String>(), b).ok());
  std::uint64_t chunks = 0;
  for (int i = 0; i < n; ++i) {
    std_msgs::msg::String m;
    m.data = "m" + std::to_string(i) + std::string(static_cast<std::size_t>(i % 50), 'x');
    EXPECT_TRUE(w.write(i % 3 ? a : b, m, 1000 + static_cast<Timestamp>(i), 1000 + static_cast<Timestamp>(i),
                        static_cast<std::uint32_t>(i))
                    .ok());
    if (chunk_ends && w.writer().stats().chunks != chunks) {
      chunks = w.writer().stats().chunks;
      chunk_ends->push_back(mem->size());  // this chunk and its message indexes end here
    }
  }
  EXPECT_TRUE(w.close().ok());
  return mem->data();
}

// Everything a user might do with a file; returns messages read by the indexed
// reader, or -1 when it refused. Must never crash.
struct Outcome {
  int indexed = -1;
  int linear = -1;
  int recovered = -1;
  Status open_status;
};

Outcome exercise(const Bytes& f, std::uint64_t max_record = std::uint64_t{1} << 32) {
  Outcome o;
  Reader r;
  ReaderOptions ro;
  ro.max_record_bytes = max_record;
  o.open_status = r.open(std::make_unique<MemoryReadable>(std::span<const std::uint8_t>(f)), ro);
  if (o.open_status.ok()) {
    int n = 0;
    Status s = r.for_each({}, [&](const MessageView& v) {
      ++n;
      return v.channel != nullptr;
    });
    o.indexed = s.ok() ? n : -1;
    if (!s.ok()) {
      EXPECT_FALSE(s.message.empty());
    }
    (void)r.scan();
    (void)r.verify();
    ReadOptions topic_b;
    topic_b.topics = {"/b"};
    topic_b.skip_bad_chunks = true;
    (void)r.for_each(topic_b, [](const MessageView&) { return true; });
  } else {
    EXPECT_FALSE(o.open_status.message.empty());
  }
  MemoryReadable src{std::span<const std::uint8_t>(f)};
  {
    LinearReader lr(src, LinearReaderOptions{true, max_record, false});
    LinearRecord rec;
    int n = 0;
    while (lr.next(rec)) n += rec.kind == LinearRecord::Kind::Message;
    o.linear = lr.status().ok() ? n : -1;
  }
  RecoverOptions rop;
  rop.max_record_bytes = max_record;
  RecoverReport rep;
  MemoryWritable out;
  if (recover(src, out, rop, rep).ok()) {
    o.recovered = static_cast<int>(rep.messages);
    // What recovery writes is always a complete, valid file with those messages.
    Reader again;
    EXPECT_TRUE(again.open(std::make_unique<MemoryReadable>(out.take())).ok());
    EXPECT_TRUE(again.complete());
    EXPECT_TRUE(again.verify().ok()) << again.verify().str();
    EXPECT_EQ(again.summary().statistics.message_count, rep.messages);
  }
  return o;
}

TEST(Corruption, TruncationAtEveryLengthKeepsEveryCompleteChunk) {
  std::vector<std::uint64_t> chunk_ends;
  const Bytes f = make_bag(150, {}, &chunk_ends);
  ASSERT_GT(chunk_ends.size(), 5U);
  // Messages held by the chunks that end at or before each chunk end.
  std::vector<std::size_t> messages_up_to(chunk_ends.size());
  for (std::size_t k = 0; k < chunk_ends.size(); ++k) {
    const Bytes whole(f.begin(), f.begin() + static_cast<std::ptrdiff_t>(chunk_ends[k]));
    MemoryReadable src(whole);
    LinearReader lr(src, LinearReaderOptions{true, std::uint64_t{1} << 32, true});
    LinearRecord rec;
    while (lr.next(rec)) messages_up_to[k] += rec.kind == LinearRecord::Kind::Message;
  }
  std::size_t data_end = 8;
  while (f[data_end] != static_cast<std::uint8_t>(Opcode::DataEnd)) {
    std::uint64_t len;
    std::memcpy(&len, f.data() + data_end + 1, 8);
    data_end += 9 + len;
  }
  // Every record boundary (and the bytes around it) gets the full treatment
  // (open, indexed and linear reads, scan, verify, recover and check what
  // recovery wrote); the other lengths, every 11th of them (the light check
  // runs at every length).
  std::vector<bool> full(f.size() + 1, false);
  for (std::size_t pos = 8; pos + 9 <= f.size();) {
    for (std::size_t d = 0; d < 3; ++d) {
      full[pos - d] = true;
      if (pos + d <= f.size()) full[pos + d] = true;
    }
    std::uint64_t len;
    std::memcpy(&len, f.data() + pos + 1, 8);
    pos += 9 + len;
  }
  Tracking t;
  for (std::size_t len = 0; len < f.size(); ++len) {
    const Bytes cut(f.begin(), f.begin() + static_cast<std::ptrdiff_t>(len));
    const bool heavy = full[len] || len % 11 == 0;
    Outcome o;
    if (heavy) {
      o = exercise(cut);
    } else {
      MemoryReadable src(cut);
      LinearReader lr(src);
      LinearRecord rec;
      int n = 0;
      while (lr.next(rec)) n += rec.kind == LinearRecord::Kind::Message;
      o.linear = lr.status().ok() ? n : -1;
    }
    if (len <= data_end) {
      // Cut before the end of the data: a linear read ends with a Truncated error, never "all fine".
      EXPECT_EQ(o.linear, -1) << "cut at " << len;
    }
    if (len < 8 + 9) continue;
    std::uint64_t header_len;
    std::memcpy(&header_len, f.data() + 9, 8);
    // Recovery mode: a gap-free prefix of what was written that holds at least
    // every message of each chunk completed before the cut.
    MemoryReadable src(cut);
    LinearReader lr(src, LinearReaderOptions{true, std::uint64_t{1} << 32, true});
    LinearRecord rec;
    std::vector<std::uint32_t> seqs;
    while (lr.next(rec)) {
      if (rec.kind == LinearRecord::Kind::Message) seqs.push_back(rec.message.sequence);
    }
    ASSERT_TRUE(lr.status().ok()) << len << ": " << lr.status().str();
    for (std::size_t i = 0; i < seqs.size(); ++i) ASSERT_EQ(seqs[i], i) << "cut at " << len;
    std::size_t complete = 0;
    while (complete < chunk_ends.size() && chunk_ends[complete] <= len) ++complete;
    if (complete > 0) {
      ASSERT_GE(seqs.size(), messages_up_to[complete - 1]) << "cut at " << len;
    }
    if (len < 8 + 9 + header_len) {
      ASSERT_TRUE(seqs.empty());
      if (heavy) {
        ASSERT_EQ(o.recovered, -1) << "cut at " << len << ": no whole header, nothing to recover";
      }
    } else if (heavy) {
      ASSERT_EQ(o.recovered, static_cast<int>(seqs.size())) << "cut at " << len;
    }
  }
  EXPECT_LT(t.largest(), std::size_t{2} << 20) << "largest single allocation while reading cut files";
  EXPECT_EQ(exercise(f).indexed, 150);
}

TEST(Corruption, BadMagicIsRefusedWithAReason) {
  Bytes f = make_bag(20);
  f[1] = 'X';
  Reader r;
  const Status s = r.open(std::make_unique<MemoryReadable>(f, "x.mcap"));
  EXPECT_EQ(s.code, StatusCode::BadMagic);
  EXPECT_NE(s.message.find("x.mcap"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("magic"), std::string::npos) << s.message;

  // A broken trailing magic: no footer is recognised, so the file is read
  // linearly, and still yields every message.
  Bytes g = make_bag(20);
  g.back() ^= 0xFF;
  Reader r2;
  ASSERT_TRUE(r2.open(std::make_unique<MemoryReadable>(g)).ok());
  EXPECT_FALSE(r2.complete());
  EXPECT_FALSE(r2.has_summary());
  int n = 0;
  EXPECT_TRUE(r2.for_each({}, [&](const MessageView&) { return ++n; }).ok());
  EXPECT_EQ(n, 20);

  // Too short to be anything.
  for (std::size_t len : {0, 3, 8, 12}) {
    Reader r3;
    EXPECT_FALSE(r3.open(std::make_unique<MemoryReadable>(Bytes(f.begin(), f.begin() + static_cast<long>(len)))).ok());
  }
}

// Byte offset of the first record with opcode `op` after the header.
std::size_t find_record(const Bytes& f, Opcode op, std::size_t from = 8) {
  std::size_t pos = from;
  while (pos + 9 <= f.size()) {
    std::uint64_t len;
    std::memcpy(&len, f.data() + pos + 1, 8);
    if (f[pos] == static_cast<std::uint8_t>(op)) return pos;
    pos += 9 + len;
  }
  return std::string::npos;
}

TEST(Corruption, AWrongChunkCrcNamesTheChunkAndCanBeSkipped) {
  WriterOptions o;
  o.compression = Compression::None;  // so a flipped byte is a clean CRC failure, not a decompression one
  Bytes f = make_bag(200, o);
  const std::size_t first = find_record(f, Opcode::Chunk);
  std::uint64_t first_len;
  std::memcpy(&first_len, f.data() + first + 1, 8);
  const std::size_t second = find_record(f, Opcode::Chunk, first + 9 + first_len);
  ASSERT_NE(second, std::string::npos);
  std::uint64_t chunk_len;
  std::memcpy(&chunk_len, f.data() + second + 1, 8);
  f[second + 9 + chunk_len - 3] ^= 0x01;  // inside the records of the second chunk

  Reader r;
  ASSERT_TRUE(r.open(std::make_unique<MemoryReadable>(f, "crc.mcap")).ok());
  int n = 0;
  Status s = r.for_each({}, [&](const MessageView&) { return ++n; });
  EXPECT_EQ(s.code, StatusCode::CrcMismatch);
  EXPECT_NE(s.message.find("crc.mcap: Chunk record at byte " + std::to_string(second)), std::string::npos) << s.message;
  EXPECT_GT(n, 0);  // the first chunk was delivered before the error

  ReadOptions skip;
  skip.skip_bad_chunks = true;
  auto cursor = r.read(skip);
  MessageView v;
  int kept = 0;
  while (cursor->next(v)) ++kept;
  EXPECT_TRUE(cursor->status().ok());
  ASSERT_EQ(cursor->problems().size(), 1U);
  EXPECT_EQ(cursor->problems()[0].offset, second);
  EXPECT_GT(kept, n);
  EXPECT_LT(kept, 200);

  // With CRC checks off the (wrong) bytes come through: the CRC is what caught it.
  ReaderOptions no_crc;
  no_crc.validate_crcs = false;
  Reader r2;
  ASSERT_TRUE(r2.open(std::make_unique<MemoryReadable>(f), no_crc).ok());
  n = 0;
  EXPECT_TRUE(r2.for_each({}, [&](const MessageView&) { return ++n; }).ok());
  EXPECT_EQ(n, 200);

  // Recovery drops that chunk only, and says so.
  MemoryReadable src(f);
  RecoverReport rep;
  MemoryWritable sink;
  ASSERT_TRUE(recover(src, sink, {}, rep).ok());
  EXPECT_EQ(rep.chunks_skipped, 1U);
  EXPECT_EQ(static_cast<int>(rep.messages), kept);
}

TEST(Corruption, AWrongSummaryOrDataCrcIsReported) {
  Bytes f = make_bag(50);
  // The statistics' message count sits in the summary: flip it.
  const std::size_t stats = find_record(f, Opcode::Statistics, find_record(f, Opcode::DataEnd));
  ASSERT_NE(stats, std::string::npos);
  Bytes g = f;
  g[stats + 9] ^= 0x01;
  Reader r;
  Status s = r.open(std::make_unique<MemoryReadable>(g));
  EXPECT_EQ(s.code, StatusCode::CrcMismatch);
  EXPECT_NE(s.message.find("summary"), std::string::npos) << s.message;
  ReaderOptions ignore;
  ignore.ignore_summary = true;
  Reader r2;
  ASSERT_TRUE(r2.open(std::make_unique<MemoryReadable>(g), ignore).ok());
  int n = 0;
  EXPECT_TRUE(r2.for_each({}, [&](const MessageView&) { return ++n; }).ok());
  EXPECT_EQ(n, 50);

  // The data section CRC (in Data End) guards bytes outside chunks, e.g. a channel record.
  Bytes h = f;
  const std::size_t channel = find_record(h, Opcode::Channel);
  h[channel + 9 + 2 + 2 + 4 + 1] ^= 0x20;  // first letter of the topic name: "/a" -> "/A"
  Reader r3;
  ASSERT_TRUE(r3.open(std::make_unique<MemoryReadable>(h)).ok());
  s = r3.verify();
  EXPECT_EQ(s.code, StatusCode::CrcMismatch);
  EXPECT_NE(s.message.find("data section"), std::string::npos) << s.message;
}

TEST(Corruption, ARecordLengthPastTheEndIsAnErrorNotAnAllocation) {
  const Bytes f = make_bag(100);
  for (Opcode op : {Opcode::Chunk, Opcode::Channel, Opcode::Schema, Opcode::MessageIndex}) {
    Bytes g = f;
    const std::size_t at = find_record(g, op);
    ASSERT_NE(at, std::string::npos);
    for (std::uint64_t len : {std::uint64_t{1} << 62, static_cast<std::uint64_t>(g.size()), std::uint64_t{~0ULL}}) {
      std::memcpy(g.data() + at + 1, &len, 8);
      Tracking t;
      MemoryReadable src(g, "long.mcap");
      LinearReader lr(src);
      LinearRecord rec;
      while (lr.next(rec)) {}
      EXPECT_EQ(lr.status().code, StatusCode::Truncated) << opcode_name(static_cast<std::uint8_t>(op));
      EXPECT_NE(lr.status().message.find("at byte " + std::to_string(at)), std::string::npos) << lr.status().message;
      (void)exercise(g);
      EXPECT_LT(t.largest(), std::size_t{2} << 20);
    }
  }
}

TEST(Corruption, ADeclaredChunkSizeCannotForceAHugeAllocation) {
  Bytes f = make_bag(100, WriterOptions{.compression = Compression::Zstd});
  const std::size_t at = find_record(f, Opcode::Chunk);
  const std::uint64_t huge = std::uint64_t{1} << 40;
  std::memcpy(f.data() + at + 9 + 16, &huge, 8);  // uncompressed_size
  Tracking t;
  const Outcome o = exercise(f);
  EXPECT_EQ(o.indexed, -1);
  EXPECT_LT(t.largest(), std::size_t{2} << 20);
  MemoryReadable src(f);
  LinearReader lr(src);
  LinearRecord rec;
  while (lr.next(rec)) {}
  EXPECT_EQ(lr.status().code, StatusCode::LimitExceeded) << lr.status().str();
}

TEST(Corruption, RandomByteFlipsNeverCrash) {
  for (Compression c : {Compression::None, Compression::Lz4, Compression::Zstd}) {
    WriterOptions o;
    o.compression = c;
    const Bytes f = make_bag(150, o);
    std::mt19937 rng(1234 + static_cast<int>(c));
    Tracking t;
    int clean = 0;
    for (int trial = 0; trial < 300; ++trial) {
      Bytes g = f;
      const int flips = 1 + static_cast<int>(rng() % 4);
      for (int k = 0; k < flips; ++k) g[rng() % g.size()] ^= static_cast<std::uint8_t>(1U << (rng() % 8));
      const Outcome out = exercise(g, std::uint64_t{64} << 20);
      clean += out.indexed == 150;
    }
    EXPECT_LT(t.largest(), std::size_t{4} << 20) << to_string(c);
    // Most flips land in payloads and must be caught by CRCs, not read back as good data.
    EXPECT_LT(clean, 300) << to_string(c);
  }
}

TEST(Corruption, UnknownChannelInAMessageIsAnErrorOrSkippedInRecovery) {
  WriterOptions o;
  o.chunked = false;
  o.crcs = false;
  Bytes f = make_bag(10, o);
  const std::size_t msg = find_record(f, Opcode::Message);
  const std::uint16_t bogus = 77;
  std::memcpy(f.data() + msg + 9, &bogus, 2);
  MemoryReadable src(f);
  LinearReader strict(src);
  LinearRecord rec;
  while (strict.next(rec)) {}
  EXPECT_EQ(strict.status().code, StatusCode::InvalidRecord);
  EXPECT_NE(strict.status().message.find("channel 77"), std::string::npos) << strict.status().message;
  RecoverReport rep;
  MemoryWritable sink;
  ASSERT_TRUE(recover(src, sink, {}, rep).ok());
  EXPECT_EQ(rep.messages, 9U);
  EXPECT_EQ(rep.problems.size(), 1U);
}

// ---------------------------------------------------------------------------- SIGKILL

TEST(Corruption, AWriterKilledWithSigkillLeavesEveryCompletedChunkReadable) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(TINYLINE_BINARY_DIR) / "bag_kill";
  fs::create_directories(dir);
  const fs::path final_path = dir / "killed.mcap";
  const fs::path path = dir / "killed.mcap.part";  // a file being written lives here until it is finished
  const fs::path fixed = dir / "recovered.mcap";
  fs::remove(final_path);
  fs::remove(path);
  int pipefd[2];
  ASSERT_EQ(::pipe(pipefd), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(pipefd[0]);
    ros2::Ros2Writer w;
    WriterOptions opt;
    opt.chunk_size_bytes = 4096;
    if (!w.open(final_path.string(), opt).ok()) ::_exit(2);
    ChannelId id;
    if (!w.add_topic("/chatter", msg::type_support<std_msgs::msg::String>(), id).ok()) ::_exit(2);
    std::uint64_t chunks = 0;
    for (std::uint32_t i = 0;; ++i) {  // writes until killed
      std_msgs::msg::String m;
      m.data = "message " + std::to_string(i);
      if (!w.write(id, m, 1000 + i, 1000 + i, i).ok()) ::_exit(3);
      if (w.writer().stats().chunks != chunks) {
        chunks = w.writer().stats().chunks;
        const std::uint64_t done = chunks;
        if (::write(pipefd[1], &done, sizeof(done)) != sizeof(done)) ::_exit(4);
      }
    }
  }
  ::close(pipefd[1]);
  std::uint64_t chunks = 0;
  while (chunks < 20) ASSERT_EQ(::read(pipefd[0], &chunks, sizeof(chunks)), static_cast<ssize_t>(sizeof(chunks)));
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  ::close(pipefd[0]);
  ASSERT_TRUE(WIFSIGNALED(status));
  EXPECT_FALSE(fs::exists(final_path));

  // The path itself was never touched. The .part file has no footer; the linear reader delivers a gap-free prefix
  // covering at least the 20 chunks the child reported, then a clear error.
  Reader r;
  ASSERT_TRUE(r.open(path.string()).ok());
  EXPECT_FALSE(r.complete());
  std::uint32_t next = 0;
  const Status s = r.for_each({}, [&](const MessageView& v) {
    EXPECT_EQ(v.message.sequence, next);
    ++next;
    return true;
  });
  EXPECT_EQ(s.code, StatusCode::Truncated) << s.str();
  EXPECT_NE(s.message.find("recover"), std::string::npos) << s.message;
  EXPECT_GT(next, 0U);

  RecoverReport rep;
  ASSERT_TRUE(recover(path.string(), fixed.string(), {}, rep).ok());
  EXPECT_EQ(rep.messages, next);
  EXPECT_GE(rep.chunks, 20U);
  EXPECT_FALSE(rep.input_complete);
  Reader fixed_reader;
  ASSERT_TRUE(fixed_reader.open(fixed.string()).ok());
  EXPECT_TRUE(fixed_reader.complete());
  EXPECT_TRUE(fixed_reader.has_summary());
  EXPECT_EQ(fixed_reader.summary().statistics.message_count, next);
  EXPECT_TRUE(fixed_reader.verify().ok()) << fixed_reader.verify().str();
}

}  // namespace
}  // namespace tinyline::bag
