// SPDX-License-Identifier: Apache-2.0
// The MCAP codec on its own: records, CRC, compression, writer and readers,
// all in memory.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>

#include <tinyline/bag/compression.hpp>
#include <tinyline/bag/crc32.hpp>
#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/ros2.hpp>
#include <tinyline/bag/writer.hpp>
#include <tinyline/msg/std_msgs/string.hpp>
#include <tinyline/msg/tinyline_msgs/line_scan.hpp>

namespace tinyline::bag {
namespace {

using Bytes = std::vector<std::uint8_t>;

Bytes bytes_of(std::string_view s) { return Bytes(s.begin(), s.end()); }

TEST(Crc32, MatchesTheZlibCheckValue) {
  EXPECT_EQ(crc32(bytes_of("123456789")), 0xCBF43926U);
  EXPECT_EQ(crc32(Bytes{}), 0U);
  // Running CRC over two pieces equals the CRC of the whole, at every split (the 16-byte loop and the tail).
  Bytes data(1000);
  std::mt19937 rng(7);
  for (auto& b : data) b = static_cast<std::uint8_t>(rng());
  const std::uint32_t whole = crc32(data);
  for (std::size_t split : {0, 1, 15, 16, 17, 500, 999, 1000}) {
    const auto a = std::span(data).first(split);
    const auto b = std::span(data).subspan(split);
    EXPECT_EQ(crc32(b, crc32(a)), whole) << "split " << split;
  }
}

TEST(Crc32, TheFastPathAgreesWithTheTablesAtEveryLengthAndAlignment) {
  Bytes data(5000 + 64);
  std::mt19937 rng(9);
  for (auto& b : data) b = static_cast<std::uint8_t>(rng());
  for (std::size_t offset = 0; offset < 16; ++offset) {
    for (std::size_t n = 0; n < 600; ++n) {
      const auto s = std::span(data).subspan(offset, n);
      ASSERT_EQ(crc32(s), crc32_portable(s)) << "offset " << offset << " length " << n;
      ASSERT_EQ(crc32(s, 0xDEADBEEF), crc32_portable(s, 0xDEADBEEF)) << "offset " << offset << " length " << n;
    }
  }
  for (std::size_t n : {1000UL, 4096UL, 4999UL, 5000UL})
    EXPECT_EQ(crc32(std::span(data).first(n)), crc32_portable(std::span(data).first(n)));
  EXPECT_EQ(crc32(bytes_of(std::string(100, 'a'))), crc32_portable(bytes_of(std::string(100, 'a'))));
}

TEST(Crc32, CombiningEqualsTheCrcOfTheConcatenation) {
  Bytes data(3000);
  std::mt19937 rng(4);
  for (auto& b : data) b = static_cast<std::uint8_t>(rng());
  for (std::size_t split : {0UL, 1UL, 7UL, 64UL, 1000UL, 2999UL, 3000UL}) {
    const auto a = std::span(data).first(split);
    const auto b = std::span(data).subspan(split);
    EXPECT_EQ(crc32_combine(crc32(a), crc32(b), b.size()), crc32(data)) << split;
  }
}

class CompressionRoundTrip : public ::testing::TestWithParam<Compression> {};

TEST_P(CompressionRoundTrip, DecompressesToTheSameBytes) {
  Compressor c(GetParam());
  std::mt19937 rng(3);
  for (std::size_t n : {0UL, 1UL, 100UL, 70000UL, 5000000UL}) {
    Bytes in(n);
    for (std::size_t i = 0; i < n; ++i) in[i] = static_cast<std::uint8_t>(i % 7 == 0 ? rng() : i / 13);
    Bytes buf, out;
    std::span<const std::uint8_t> comp;
    ASSERT_TRUE(c.compress(in, buf, comp).ok());
    const Status s = decompress(mcap_name(GetParam()), comp, n, 1ULL << 32, out, "test");
    ASSERT_TRUE(s.ok()) << s.str();
    EXPECT_EQ(out, in) << n << " bytes";
  }
}

TEST_P(CompressionRoundTrip, RefusesAWrongDeclaredSize) {
  Compressor c(GetParam());
  Bytes in(1000, 42), buf, out;
  std::span<const std::uint8_t> comp;
  ASSERT_TRUE(c.compress(in, buf, comp).ok());
  Status s = decompress(mcap_name(GetParam()), comp, 999, 1ULL << 32, out, "chunk X");
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message.find("chunk X"), std::string::npos) << s.message;
  s = decompress(mcap_name(GetParam()), comp, 1001, 1ULL << 32, out, "chunk X");
  EXPECT_FALSE(s.ok());
  s = decompress(mcap_name(GetParam()), comp, 1000, 999, out, "chunk X");
  EXPECT_EQ(s.code, StatusCode::LimitExceeded);
}

INSTANTIATE_TEST_SUITE_P(All, CompressionRoundTrip,
                         ::testing::Values(Compression::None, Compression::Lz4, Compression::Zstd),
                         [](const auto& info) { return std::string(to_string(info.param)); });

TEST(Compression, CorruptStreamsAreErrorsNotCrashes) {
  for (Compression c : {Compression::Lz4, Compression::Zstd}) {
    Compressor comp(c);
    Bytes in(50000);
    for (std::size_t i = 0; i < in.size(); ++i) in[i] = static_cast<std::uint8_t>(i * 31 / 7);
    Bytes zbuf, out;
    std::span<const std::uint8_t> zs;
    ASSERT_TRUE(comp.compress(in, zbuf, zs).ok());
    const Bytes z(zs.begin(), zs.end());
    std::mt19937 rng(11);
    for (int trial = 0; trial < 200; ++trial) {
      Bytes bad = z;
      bad[rng() % bad.size()] ^= static_cast<std::uint8_t>(1U << (rng() % 8));
      const Status s = decompress(mcap_name(c), bad, in.size(), 1ULL << 32, out, "flip");
      if (s.ok()) {
        EXPECT_EQ(out.size(), in.size());  // a flip in a literal may decode; the chunk CRC catches it
      }
    }
    // Truncated streams.
    for (std::size_t cut : {std::size_t{0}, std::size_t{4}, z.size() / 2, z.size() - 1}) {
      const Status s = decompress(mcap_name(c), std::span(z).first(cut), in.size(), 1ULL << 32, out, "cut");
      EXPECT_FALSE(s.ok()) << to_string(c) << " cut at " << cut;
    }
  }
  Bytes out;
  EXPECT_EQ(decompress("brotli", Bytes{1, 2}, 2, 100, out, "w").code, StatusCode::Unsupported);
}

// ---------------------------------------------------------------------------- writer + readers

struct Sample {
  std::string topic;
  Timestamp t;
  std::string text;
};

// Writes std_msgs/String messages on a few topics; returns the file bytes.
Bytes write_strings(const std::vector<Sample>& samples, WriterOptions opt) {
  ros2::Ros2Writer w;
  auto sink = std::make_unique<MemoryWritable>();
  auto* mem = sink.get();
  EXPECT_TRUE(w.open(std::move(sink), opt).ok());
  std::map<std::string, ChannelId> ids;
  std::uint32_t seq = 0;
  for (const auto& s : samples) {
    if (!ids.count(s.topic)) {
      ChannelId id;
      EXPECT_TRUE(w.add_topic(s.topic, msg::type_support<std_msgs::msg::String>(), id).ok());
      ids[s.topic] = id;
    }
    std_msgs::msg::String m;
    m.data = s.text;
    EXPECT_TRUE(w.write(ids[s.topic], m, s.t, s.t + 1, ++seq).ok());
  }
  auto keep = w.writer().sink();
  (void)keep;
  EXPECT_TRUE(w.close().ok());
  return mem->data();
}

std::vector<Sample> make_samples(int n, std::uint32_t seed = 1) {
  std::mt19937 rng(seed);
  std::vector<Sample> out;
  const char* topics[] = {"/a", "/b", "/c"};
  for (int i = 0; i < n; ++i) {
    out.push_back({topics[rng() % 3], 1000 + static_cast<Timestamp>(i) * 10, "msg " + std::to_string(i)});
  }
  return out;
}

std::vector<Sample> read_all(Reader& r, const ReadOptions& ro = {}) {
  std::vector<Sample> out;
  const Status s = r.for_each(ro, [&](const MessageView& v) {
    std_msgs::msg::String m;
    EXPECT_TRUE(msg::deserialize(v.message.data, m)) << v.channel->topic;
    out.push_back({v.channel->topic, v.message.log_time, m.data});
    return true;
  });
  EXPECT_TRUE(s.ok()) << s.str();
  return out;
}

bool same(const std::vector<Sample>& a, const std::vector<Sample>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i].topic != b[i].topic || a[i].t != b[i].t || a[i].text != b[i].text) return false;
  }
  return true;
}

struct Variant {
  std::string name;
  WriterOptions opt;
};

std::vector<Variant> variants() {
  std::vector<Variant> v;
  for (Compression c : {Compression::None, Compression::Lz4, Compression::Zstd}) {
    WriterOptions o;
    o.compression = c;
    o.chunk_size_bytes = 2000;  // many chunks
    v.push_back({std::string(to_string(c)), o});
  }
  WriterOptions unchunked;
  unchunked.chunked = false;
  v.push_back({"unchunked", unchunked});
  WriterOptions no_summary;
  no_summary.summary = false;
  v.push_back({"no_summary", no_summary});
  WriterOptions no_index;
  no_index.message_indexes = false;
  no_index.chunk_size_bytes = 1500;
  v.push_back({"no_message_index", no_index});
  WriterOptions no_crc;
  no_crc.crcs = false;
  v.push_back({"no_crc", no_crc});
  return v;
}

class WriterVariants : public ::testing::TestWithParam<Variant> {};

TEST_P(WriterVariants, EveryReaderReturnsWhatWasWritten) {
  const auto samples = make_samples(500);
  const Bytes file = write_strings(samples, GetParam().opt);
  Reader r;
  ASSERT_TRUE(r.open(std::make_unique<MemoryReadable>(file)).ok());
  EXPECT_TRUE(r.complete());
  EXPECT_EQ(r.header().profile, "ros2");
  EXPECT_EQ(r.has_summary(), GetParam().opt.summary);
  EXPECT_TRUE(same(read_all(r), samples));

  // Topic filter and time range.
  ReadOptions ro;
  ro.topics = {"/b"};
  ro.start_time = 2000;
  ro.end_time = 4000;
  std::vector<Sample> want;
  for (const auto& s : samples)
    if (s.topic == "/b" && s.t >= 2000 && s.t < 4000) want.push_back(s);
  EXPECT_TRUE(same(read_all(r, ro), want));

  // File order gives the same here (written in time order).
  ro = {};
  ro.order = ReadOrder::File;
  EXPECT_TRUE(same(read_all(r, ro), samples));

  // The linear reader agrees and checks every CRC.
  MemoryReadable src(file);
  LinearReader lr(src);
  std::vector<Sample> linear;
  LinearRecord rec;
  while (lr.next(rec)) {
    if (rec.kind != LinearRecord::Kind::Message) continue;
    std_msgs::msg::String m;
    ASSERT_TRUE(msg::deserialize(rec.message.data, m));
    linear.push_back({rec.channel->topic, rec.message.log_time, m.data});
  }
  EXPECT_TRUE(lr.status().ok()) << lr.status().str();
  EXPECT_TRUE(lr.data_end_seen());
  EXPECT_TRUE(same(linear, samples));
  EXPECT_TRUE(r.verify().ok()) << r.verify().str();
}

TEST_P(WriterVariants, StatisticsAndSummaryAgreeWithTheData) {
  const auto samples = make_samples(300, 5);
  const Bytes file = write_strings(samples, GetParam().opt);
  Reader r;
  ASSERT_TRUE(r.open(std::make_unique<MemoryReadable>(file)).ok());
  if (!r.has_summary()) {
    ASSERT_TRUE(r.scan().ok());
  }
  const auto& st = r.summary().statistics;
  EXPECT_EQ(st.message_count, samples.size());
  EXPECT_EQ(st.message_start_time, samples.front().t);
  EXPECT_EQ(st.message_end_time, samples.back().t);
  EXPECT_EQ(r.channels().size(), 3U);
  EXPECT_EQ(r.schemas().size(), 1U);  // one type, registered once
  std::map<std::string, std::uint64_t> per_topic;
  for (const auto& s : samples) ++per_topic[s.topic];
  for (const auto& [id, ch] : r.channels()) {
    EXPECT_EQ(st.channel_message_counts.at(id), per_topic[ch.topic]) << ch.topic;
    EXPECT_EQ(ch.message_encoding, "cdr");
    EXPECT_NE(ch.metadata.at("offered_qos_profiles").find("reliability: 1"), std::string::npos);
  }
  const auto& schema = r.schemas().begin()->second;
  EXPECT_EQ(schema.name, "std_msgs/msg/String");
  EXPECT_EQ(schema.encoding, "ros2msg");
}

INSTANTIATE_TEST_SUITE_P(All, WriterVariants, ::testing::ValuesIn(variants()),
                         [](const auto& info) { return info.param.name; });

TEST(Writer, MergesOutOfOrderChunksByLogTime) {
  // Log times jump back and forth across chunks: the indexed reader still returns ascending time.
  std::vector<Sample> samples;
  for (int i = 0; i < 400; ++i) {
    const Timestamp t = 1'000'000 + static_cast<Timestamp>((i * 7919) % 400) * 1000;
    samples.push_back({i % 2 ? "/x" : "/y", t, std::to_string(i)});
  }
  WriterOptions o;
  o.chunk_size_bytes = 1000;
  const Bytes file = write_strings(samples, o);
  Reader r;
  ASSERT_TRUE(r.open(std::make_unique<MemoryReadable>(file)).ok());
  ASSERT_GT(r.summary().chunk_indexes.size(), 5U);
  const auto got = read_all(r);
  ASSERT_EQ(got.size(), samples.size());
  EXPECT_TRUE(std::is_sorted(got.begin(), got.end(), [](const Sample& a, const Sample& b) { return a.t < b.t; }));
  ReadOptions file_order;
  file_order.order = ReadOrder::File;
  EXPECT_TRUE(same(read_all(r, file_order), samples));
}

TEST(Writer, LargeMessagesGetChunksOfTheirOwnStoredWhenIncompressible) {
  for (Compression c : {Compression::None, Compression::Lz4, Compression::Zstd}) {
    Writer w;
    MemoryWritable mem;
    WriterOptions o;
    o.compression = c;
    o.chunk_size_bytes = 64 * 1024;
    ASSERT_TRUE(w.open(std::make_unique<WritableRef>(mem), o).ok());
    Schema s{0, "raw", "", ""};
    ASSERT_TRUE(w.add_schema(s).ok());
    Channel small{0, s.id, "/small", "x", {}}, big{0, s.id, "/big", "x", {}};
    ASSERT_TRUE(w.add_channel(small).ok());
    ASSERT_TRUE(w.add_channel(big).ok());
    std::mt19937 rng(5);
    std::vector<Bytes> payloads;
    std::vector<ChannelId> channel_of;
    // 25 large messages: 5 of noise (incompressible), then 20 of zeros; small ones between.
    for (int i = 0; i < 100; ++i) {
      const bool large = i % 4 == 0;
      Bytes b(large ? 100000 : 300);
      const bool noisy = i < 20;
      for (auto& x : b)
        x = large && noisy ? static_cast<std::uint8_t>(rng()) : static_cast<std::uint8_t>(large ? 0 : i);
      payloads.push_back(b);
      channel_of.push_back(large ? big.id : small.id);
      Message m;
      m.channel_id = channel_of.back();
      m.log_time = m.publish_time = 100 + static_cast<Timestamp>(i);
      m.data = payloads.back();
      ASSERT_TRUE(w.write(m).ok());
    }
    ASSERT_TRUE(w.close().ok());
    Reader r;
    ASSERT_TRUE(r.open(std::make_unique<MemoryReadable>(mem.data())).ok());
    std::map<std::string, int> by_compression;
    for (const auto& ci : r.summary().chunk_indexes) {
      if (ci.message_index_offsets.count(big.id)) {
        EXPECT_EQ(ci.message_index_offsets.size(), 1U) << "a large message shares its chunk";
        ++by_compression[ci.compression];
      }
    }
    EXPECT_EQ(by_compression[""] + by_compression["lz4"] + by_compression["zstd"], 25) << to_string(c);
    if (c == Compression::None) {
      EXPECT_EQ(by_compression[""], 25);
    } else {
      // The first noisy one is tried and stored; the next 15 large ones are stored
      // without trying (4 noisy, 11 zero-filled); from the 17th on it compresses again.
      EXPECT_EQ(by_compression[""], 16) << to_string(c);
      EXPECT_EQ(by_compression[std::string(mcap_name(c))], 9) << to_string(c);
    }
    ReadOptions file_order;
    file_order.order = ReadOrder::File;
    std::size_t i = 0;
    ASSERT_TRUE(r.for_each(file_order, [&](const MessageView& v) {
                   EXPECT_EQ(Bytes(v.message.data.begin(), v.message.data.end()), payloads[i]) << i;
                   EXPECT_EQ(v.message.channel_id, channel_of[i]);
                   ++i;
                   return true;
                 }).ok());
    EXPECT_EQ(i, payloads.size());
    EXPECT_TRUE(r.verify().ok()) << r.verify().str();
  }
}

TEST(Writer, RefusesUnknownChannelsAndSchemas) {
  Writer w;
  ASSERT_TRUE(w.open(std::make_unique<MemoryWritable>()).ok());
  Message m;
  m.channel_id = 3;
  Status s = w.write(m);
  EXPECT_EQ(s.code, StatusCode::InvalidArgument);
  EXPECT_NE(s.message.find("channel 3"), std::string::npos) << s.message;
  Channel c;
  c.topic = "/t";
  c.schema_id = 9;
  s = w.add_channel(c);
  EXPECT_EQ(s.code, StatusCode::InvalidArgument);
  EXPECT_TRUE(w.close().ok());
  EXPECT_EQ(w.write(m).code, StatusCode::NotOpen);
}

TEST(Writer, AnEmptyFileIsValid) {
  Writer w;
  auto sink = std::make_unique<MemoryWritable>();
  auto* mem = sink.get();
  ASSERT_TRUE(w.open(std::move(sink)).ok());
  ASSERT_TRUE(w.close().ok());
  Reader r;
  ASSERT_TRUE(r.open(std::make_unique<MemoryReadable>(mem->data())).ok());
  EXPECT_TRUE(r.complete());
  EXPECT_EQ(r.summary().statistics.message_count, 0U);
  EXPECT_TRUE(read_all(r).empty());
  EXPECT_TRUE(r.verify().ok());
}

TEST(Writer, AttachmentsAndMetadataRoundTrip) {
  Writer w;
  auto sink = std::make_unique<MemoryWritable>();
  auto* mem = sink.get();
  ASSERT_TRUE(w.open(std::move(sink)).ok());
  const Bytes blob = bytes_of("calibration: 42");
  Attachment a;
  a.name = "calib.yaml";
  a.media_type = "application/yaml";
  a.log_time = 5;
  a.data = blob;
  ASSERT_TRUE(w.write(a).ok());
  Metadata md;
  md.name = "recorder";
  md.metadata = {{"dropped", "0"}, {"host", "test"}};
  ASSERT_TRUE(w.write(md).ok());
  ASSERT_TRUE(w.close().ok());

  Reader r;
  ASSERT_TRUE(r.open(std::make_unique<MemoryReadable>(mem->data())).ok());
  ASSERT_EQ(r.summary().attachment_indexes.size(), 1U);
  ASSERT_EQ(r.summary().metadata_indexes.size(), 1U);
  Bytes buf;
  Attachment got;
  ASSERT_TRUE(r.read_attachment(r.summary().attachment_indexes[0], buf, got).ok());
  EXPECT_EQ(got.name, "calib.yaml");
  EXPECT_EQ(Bytes(got.data.begin(), got.data.end()), blob);
  Metadata gm;
  ASSERT_TRUE(r.read_metadata(r.summary().metadata_indexes[0], gm).ok());
  EXPECT_EQ(gm.metadata, md.metadata);
  EXPECT_TRUE(r.verify().ok());
}

// A file assembled record by record, with records of opcodes this reader does not know.
TEST(Reader, SkipsUnknownOpcodesInTheDataSectionAndInChunks) {
  Bytes f(kMagic.begin(), kMagic.end());
  serialize(Header{"ros2", "hand-made"}, f);
  auto unknown = [](Bytes& out, std::uint8_t op) {
    out.push_back(op);
    const std::uint64_t len = 5;
    out.insert(out.end(), reinterpret_cast<const std::uint8_t*>(&len), reinterpret_cast<const std::uint8_t*>(&len) + 8);
    for (int i = 0; i < 5; ++i) out.push_back(0xAB);
  };
  unknown(f, 0x80);
  Schema s = ros2::schema_for(msg::type_support<std_msgs::msg::String>());
  s.id = 1;
  serialize(s, f);
  Channel c = ros2::channel_for("/t", 1, {ros2::QosProfile{}});
  c.id = 1;
  serialize(c, f);
  std_msgs::msg::String m;
  m.data = "hello";
  const Bytes payload = msg::serialize(m);
  Bytes records;
  unknown(records, 0x99);
  Message msg;
  msg.channel_id = 1;
  msg.log_time = 10;
  msg.publish_time = 10;
  msg.data = payload;
  serialize(msg, records);
  Chunk ch;
  ch.message_start_time = ch.message_end_time = 10;
  ch.uncompressed_size = records.size();
  ch.uncompressed_crc = crc32(records);
  ch.records = records;
  serialize(ch, f);
  unknown(f, 0xFE);
  msg.log_time = 20;
  serialize(msg, f);  // a message outside any chunk
  serialize(DataEnd{}, f);
  serialize(Footer{}, f);
  f.insert(f.end(), kMagic.begin(), kMagic.end());

  Reader r;
  ASSERT_TRUE(r.open(std::make_unique<MemoryReadable>(f)).ok());
  EXPECT_FALSE(r.has_summary());
  std::vector<Timestamp> times;
  ASSERT_TRUE(r.for_each({}, [&](const MessageView& v) {
                 times.push_back(v.message.log_time);
                 return true;
               }).ok());
  EXPECT_EQ(times, (std::vector<Timestamp>{10, 20}));
  ASSERT_TRUE(r.scan().ok());
  EXPECT_EQ(r.summary().statistics.message_count, 2U);
}

TEST(Ros2, QosYamlHasRosbag2Fields) {
  ros2::QosProfile p;
  p.depth = 7;
  p.reliability = ros2::QosProfile::Reliability::BestEffort;
  const std::string y = ros2::offered_qos_profiles_yaml({p});
  for (const char* key : {"history: 1", "depth: 7", "reliability: 2", "durability: 2", "deadline:", "lifespan:",
                          "liveliness: 1", "liveliness_lease_duration:", "avoid_ros_namespace_conventions: false"}) {
    EXPECT_NE(y.find(key), std::string::npos) << key << " in\n" << y;
  }
}

TEST(Ros2, SchemaCarriesDependenciesTheRosbag2Way) {
  const Schema s = ros2::schema_for(msg::type_support<tinyline_msgs::msg::LineScan>());
  EXPECT_EQ(s.name, "tinyline_msgs/msg/LineScan");
  EXPECT_NE(s.data.find(std::string(80, '=') + "\nMSG: std_msgs/Header\n"), std::string::npos) << s.data;
  EXPECT_NE(s.data.find("MSG: builtin_interfaces/Time\n"), std::string::npos);
}

}  // namespace
}  // namespace tinyline::bag
