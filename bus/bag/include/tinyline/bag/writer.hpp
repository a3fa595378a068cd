// SPDX-License-Identifier: Apache-2.0
// The MCAP writer. Messages go into chunks (compressed with lz4 or zstd, or
// stored); each closed chunk is followed by one message index per channel and
// handed to the OS at once, so a writer killed mid-file leaves every completed
// chunk readable. close() writes the data end record, the summary (schemas,
// channels, statistics, chunk, attachment and metadata indexes), the summary
// offsets and the footer.
//
// Schema and channel records go to the data section as soon as they are
// added, outside any chunk: a damaged chunk then never takes the definition of
// a channel with it (the recovery tool relies on this).
//
// Not thread-safe: one thread writes (the recorder gives the writer its own).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <tinyline/bag/compression.hpp>
#include <tinyline/bag/io.hpp>
#include <tinyline/bag/records.hpp>

namespace tinyline::bag {

struct WriterOptions {
  /// Header profile: "ros2" for ROS 2 bags (what the recorder writes).
  std::string profile = "ros2";
  /// Header library field.
  std::string library = "tinyline-bag 0.1";
  Compression compression = Compression::Lz4;
  /// lz4: 0 (fast) or 1..12 (high compression); zstd: 1..19, 0 = library default.
  int compression_level = 0;
  /// A chunk is closed once its uncompressed records reach this size [bytes].
  std::uint64_t chunk_size_bytes = 1 << 20;
  /// false: messages go straight to the data section (no compression, no index).
  bool chunked = true;
  /// One message index record per channel after each chunk (indexed reads by topic and time).
  bool message_indexes = true;
  /// Summary section: schema and channel copies, statistics, chunk indexes.
  bool summary = true;
  /// Summary offset records (one per opcode group of the summary).
  bool summary_offsets = true;
  /// CRCs of chunks, the data section, the summary and attachments.
  bool crcs = true;
  /// Store a chunk uncompressed when compression saves under 3% (noisy point
  /// clouds): readers then skip decompressing it too. After a large message
  /// (one that fills a chunk) did not compress, the next 15 of its topic are
  /// stored without trying, then compression is tried again.
  bool skip_incompressible = true;
  /// Hand every finished chunk to the OS at once (crash safety); false leaves it to the buffer.
  bool flush_every_chunk = true;
};

struct WriterStats {
  std::uint64_t messages = 0;
  std::uint64_t chunks = 0;
  std::uint64_t message_bytes = 0;       ///< payload bytes of all messages
  std::uint64_t uncompressed_bytes = 0;  ///< chunk records before compression
  std::uint64_t file_bytes = 0;          ///< bytes written so far
};

class Writer {
 public:
  Writer() = default;
  /// Closes the file if still open (a failure there is lost: call close() to see it).
  ~Writer();
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  /// Writes to `path` through a FileWritable: to "<path>.part" until close()
  /// renames it into place (a failed close() leaves the path as it was).
  Status open(const std::string& path, WriterOptions options = {});
  /// Writes to any sink (memory in tests).
  Status open(std::unique_ptr<Writable> out, WriterOptions options = {});
  bool is_open() const { return out_ != nullptr; }

  /// Registers a schema and writes its record; fills schema.id. An identical
  /// schema registered before gets the same id.
  Status add_schema(Schema& schema);
  /// Registers a channel and writes its record; fills channel.id. Its schema
  /// must be registered (or 0).
  Status add_channel(Channel& channel);

  /// Appends one message; its channel must be registered.
  Status write(const Message& message);

  /// Attachments and metadata go to the data section (outside chunks) and are indexed in the summary.
  Status write(const Attachment& attachment);
  Status write(const Metadata& metadata);

  /// Closes the open chunk now (the recorder does it on a quiet period so the
  /// file on disk is never far behind).
  Status flush();

  /// Finishes the file: last chunk, data end, summary, footer. Idempotent.
  /// After an error the sink is abandoned instead (a file keeps its old content).
  Status close();

  const WriterStats& stats() const { return stats_; }
  /// Uncompressed bytes in the chunk not yet closed.
  std::uint64_t open_chunk_bytes() const { return chunk_records_.size(); }
  const WriterOptions& options() const { return options_; }
  /// The sink, e.g. to read back a MemoryWritable after close().
  Writable* sink() { return out_.get(); }
  /// Keeps the sink after close() (for memory sinks), releasing it from the writer.
  std::unique_ptr<Writable> release_sink() { return std::move(closed_out_); }

 private:
  Status emit(std::span<const std::uint8_t> bytes, bool update_crc = true);  // to the file (and the data CRC)
  Status close_chunk(ChannelId large_channel = 0);
  Status write_large(const Message& m);
  Status emit_chunk(std::span<const std::uint8_t> a, std::span<const std::uint8_t> b, std::uint32_t crc,
                    std::uint64_t uncompressed_size, std::string_view comp);
  static constexpr std::uint8_t kSkipAfterIncompressible = 15;
  Status fail(Status s);
  /// The summary records (schemas, channels, statistics, indexes), noting each group in `offsets`.
  std::vector<std::uint8_t> summary_section(std::uint64_t summary_start, std::vector<SummaryOffset>& offsets);
  Status write_summary_and_footer();

  WriterOptions options_;
  std::unique_ptr<Writable> out_;
  std::unique_ptr<Writable> closed_out_;
  std::unique_ptr<Compressor> compressor_;
  Status error_;  // sticky: after a write error every call returns it

  std::vector<Schema> schemas_;    // index = id - 1
  std::vector<Channel> channels_;  // index = id
  std::vector<ChunkIndex> chunk_indexes_;
  std::vector<AttachmentIndex> attachment_indexes_;
  std::vector<MetadataIndex> metadata_indexes_;
  Statistics statistics_;
  bool have_time_ = false;

  // The open chunk.
  std::vector<std::uint8_t> chunk_records_;
  std::vector<std::uint8_t> compressed_;
  std::vector<std::uint8_t> scratch_;
  std::vector<std::uint8_t> prefix_;
  std::vector<std::uint8_t> skip_compression_;  // per channel: large messages left to store without trying
  std::vector<std::vector<MessageIndexEntry>> chunk_entries_;  // per channel id
  std::vector<ChannelId> chunk_channels_;                      // channels with entries, in first-use order
  Timestamp chunk_start_ = 0;
  Timestamp chunk_end_ = 0;
  std::uint64_t chunk_messages_ = 0;

  std::uint32_t data_crc_ = 0;
  WriterStats stats_;
};

}  // namespace tinyline::bag
