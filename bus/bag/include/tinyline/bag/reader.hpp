// SPDX-License-Identifier: Apache-2.0
// MCAP readers.
//
//  Reader         opens a file through its footer and summary: schemas,
//                 channels, statistics and chunk indexes without reading the
//                 data. read() returns messages of chosen topics in a time
//                 range, in log-time order, decompressing only the chunks that
//                 hold them. A file with no summary (a writer that died, or one
//                 that wrote none) is read linearly instead.
//  LinearReader   streams the records from the start; needs no summary;
//                 flattens chunks; skips unknown opcodes. In recovery mode it
//                 skips a damaged chunk and ends cleanly at a truncated tail,
//                 noting each problem.
//
// Nothing a file says is trusted: a record length past the end of the file, a
// chunk whose size exceeds ReaderOptions::max_record_bytes, a wrong CRC or a
// corrupt compressed stream is a Status naming the record and its byte
// offset, never a crash or an allocation the file's size does not justify.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <tinyline/bag/io.hpp>
#include <tinyline/bag/records.hpp>

namespace tinyline::bag {

struct ReaderOptions {
  /// Check chunk CRCs (and, on linear reads that reach it, the data section
  /// CRC; the summary CRC when opening).
  bool validate_crcs = true;
  /// The largest record or decompressed chunk accepted [bytes].
  std::uint64_t max_record_bytes = std::uint64_t{1} << 32;
  /// Ignore the summary and read linearly (for files whose summary is suspect).
  bool ignore_summary = false;
};

enum class ReadOrder {
  LogTime,  ///< ascending log time (ties in file order); needs chunk indexes, else file order
  File,     ///< the order records appear in the file
};

struct ReadOptions {
  std::vector<std::string> topics;                             ///< empty: every topic
  Timestamp start_time = 0;                                    ///< inclusive
  Timestamp end_time = std::numeric_limits<Timestamp>::max();  ///< exclusive
  ReadOrder order = ReadOrder::LogTime;
  /// Skip chunks that fail to decompress or check, noting them in problems(),
  /// instead of stopping with an error.
  bool skip_bad_chunks = false;
};

struct MessageView {
  Message message;  ///< data valid until the next call to next()
  const Channel* channel = nullptr;
  const Schema* schema = nullptr;  ///< nullptr for schemaless channels
};

/// A problem met (and, in recovery mode, stepped over) while reading.
struct ReadProblem {
  std::uint64_t offset = 0;  ///< byte offset of the record concerned
  Status status;
  bool chunk_dropped = false;  ///< the rest of a chunk (or all of it) was skipped
};

/// Pull-style message iteration.
class MessageCursor {
 public:
  virtual ~MessageCursor() = default;
  /// The next message, or false at the end or on an error (then status() says which).
  virtual bool next(MessageView& out) = 0;
  virtual const Status& status() const = 0;
  /// Chunks skipped because of ReadOptions::skip_bad_chunks.
  virtual const std::vector<ReadProblem>& problems() const = 0;
};

/// One record from the linear reader, chunks flattened.
struct LinearRecord {
  enum class Kind { Header, Schema, Channel, Message, Attachment, Metadata, ChunkBegin, DataEnd, Footer };
  Kind kind = Kind::Header;
  std::uint8_t opcode = 0;
  std::uint64_t offset = 0;  ///< file offset of the record (of its chunk for records inside one)
  bool in_chunk = false;
  const Header* header = nullptr;
  const Schema* schema = nullptr;    ///< Schema records; the message's schema for Message
  const Channel* channel = nullptr;  ///< Channel records; the message's channel for Message
  Message message;
  Attachment attachment;
  const Metadata* metadata = nullptr;
  const Chunk* chunk = nullptr;  ///< ChunkBegin (records span empty)
};

struct LinearReaderOptions {
  bool validate_crcs = true;
  std::uint64_t max_record_bytes = std::uint64_t{1} << 32;
  /// Recovery: skip a chunk that fails (CRC, decompression, inner records) and
  /// end without error at a truncated tail; every problem is kept in problems().
  bool recover = false;
};

class LinearReader {
 public:
  /// `source` must outlive the reader.
  explicit LinearReader(Readable& source, LinearReaderOptions options = {});
  ~LinearReader();
  LinearReader(const LinearReader&) = delete;
  LinearReader& operator=(const LinearReader&) = delete;

  /// The next record, or false at the end of the data section (after its Data
  /// End record, or a footer) or on an error (status() says which). A file
  /// that stops without either is Truncated (recovery mode: a problem, no error).
  bool next(LinearRecord& out);
  const Status& status() const;
  const std::vector<ReadProblem>& problems() const;
  /// Bytes of the file consumed as valid records so far.
  std::uint64_t position() const;
  const std::map<SchemaId, Schema>& schemas() const;
  const std::map<ChannelId, Channel>& channels() const;
  /// True once a Data End record was read (and, with CRCs on, its data CRC matched).
  bool data_end_seen() const;
  bool footer_seen() const;

  /// Recovery: definitions known from elsewhere (the summary, under its own
  /// CRC). Messages on these channels resolve even when the file's own
  /// records are lost; a record of the file that disagrees is replaced by the
  /// known one (and noted in problems()).
  void know(const std::map<SchemaId, Schema>& schemas, const std::map<ChannelId, Channel>& channels);
  /// Recovery: reads the one chunk at `offset` next (a chunk index points
  /// there), then ends. For chunks a damaged record made the linear pass miss.
  bool read_chunk_at(std::uint64_t offset);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// What a file says about itself (from its summary, or rebuilt by a scan).
struct BagSummary {
  Header header;
  std::map<SchemaId, Schema> schemas;
  std::map<ChannelId, Channel> channels;
  Statistics statistics;
  std::vector<ChunkIndex> chunk_indexes;
  std::vector<AttachmentIndex> attachment_indexes;
  std::vector<MetadataIndex> metadata_indexes;
  std::map<std::string, std::uint64_t> chunks_by_compression;  ///< "zstd" -> count ("" = none)
  bool from_summary_section = false;                           ///< false: rebuilt by reading the file linearly
  bool complete = false;                                       ///< the file ends with a footer and magic
};

class Reader {
 public:
  Reader() = default;
  ~Reader();
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  /// Checks the magic and header, then the footer and summary. A file without
  /// footer or summary opens fine (has_summary() false); a summary that is
  /// present but broken is an error.
  Status open(const std::string& path, ReaderOptions options = {});
  Status open(std::unique_ptr<Readable> source, ReaderOptions options = {});

  bool has_summary() const { return has_summary_; }
  /// True when the file ends with a valid footer and magic.
  bool complete() const { return complete_; }
  const Header& header() const { return summary_.header; }
  /// From the summary; empty until scan() for a file without one.
  const std::map<SchemaId, Schema>& schemas() const { return summary_.schemas; }
  const std::map<ChannelId, Channel>& channels() const { return summary_.channels; }
  const BagSummary& summary() const { return summary_; }

  /// Fills summary() by reading the whole file (when it has no summary
  /// section). Returns the first error met; what was read before it is kept.
  Status scan();

  /// Messages of the chosen topics in [start, end). Indexed when the file
  /// has chunk indexes, else a linear read.
  std::unique_ptr<MessageCursor> read(const ReadOptions& options = {});
  /// Calls fn for each message until it returns false. Returns the cursor's status.
  Status for_each(const ReadOptions& options, const std::function<bool(const MessageView&)>& fn);

  /// Reads an attachment or metadata record that the summary indexes.
  Status read_attachment(const AttachmentIndex& index, std::vector<std::uint8_t>& data, Attachment& out);
  Status read_metadata(const MetadataIndex& index, Metadata& out);

  /// Reads every record from the start, checking every CRC (data section
  /// included) and that the summary agrees with the data. For `bag info --verify`.
  Status verify();

  Readable& source() { return *source_; }
  const ReaderOptions& options() const { return options_; }

 private:
  Status open_summary(std::uint64_t footer_offset, const Footer& footer);
  /// The footer's summary and offsets lie inside the file, within the size limit.
  Status check_summary_place(std::uint64_t footer_offset, const Footer& footer) const;
  /// One summary record into summary_ (`w` names it for errors).
  Status summary_record(std::uint8_t op, std::span<const std::uint8_t> content, const std::string& w,
                        const Footer& footer, bool& have_stats);
  /// Statistics for a summary without a Statistics record.
  void statistics_from_chunk_indexes();
  std::string where(std::uint64_t offset, std::string_view what) const;

  std::unique_ptr<Readable> source_;
  ReaderOptions options_;
  BagSummary summary_;
  bool has_summary_ = false;
  bool complete_ = false;
  std::uint64_t data_start_ = 0;
};

}  // namespace tinyline::bag
