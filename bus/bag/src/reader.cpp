// SPDX-License-Identifier: Apache-2.0
#include <algorithm>
#include <cstring>
#include <queue>
#include <set>

#include <fmt/format.h>

#include <tinyline/bag/compression.hpp>
#include <tinyline/bag/crc32.hpp>
#include <tinyline/bag/reader.hpp>

#include "wire.hpp"

namespace tinyline::bag {

namespace {

std::set<ChannelId> wanted_channels(const std::map<ChannelId, Channel>& channels,
                                    const std::vector<std::string>& topics) {
  std::set<ChannelId> ids;
  for (const auto& [id, ch] : channels) {
    if (topics.empty() || std::find(topics.begin(), topics.end(), ch.topic) != topics.end()) ids.insert(id);
  }
  return ids;
}

// ---------------------------------------------------------------------------- LinearCursor

// Messages in file order from a linear read (files without chunk indexes).
class LinearCursor final : public MessageCursor {
 public:
  LinearCursor(Readable& src, const ReaderOptions& ro, ReadOptions opts)
      : opts_(std::move(opts)),
        reader_(src, LinearReaderOptions{ro.validate_crcs, ro.max_record_bytes, opts_.skip_bad_chunks}) {}

  bool next(MessageView& out) override {
    LinearRecord r;
    while (reader_.next(r)) {
      if (r.kind != LinearRecord::Kind::Message) continue;
      if (r.message.log_time < opts_.start_time || r.message.log_time >= opts_.end_time) continue;
      if (!opts_.topics.empty() &&
          std::find(opts_.topics.begin(), opts_.topics.end(), r.channel->topic) == opts_.topics.end())
        continue;
      out.message = r.message;
      out.channel = r.channel;
      out.schema = r.schema;
      return true;
    }
    return false;
  }
  const Status& status() const override { return reader_.status(); }
  const std::vector<ReadProblem>& problems() const override { return reader_.problems(); }

 private:
  ReadOptions opts_;
  LinearReader reader_;
};

// ---------------------------------------------------------------------------- IndexedCursor

// Messages through the chunk indexes: only chunks that overlap the time range
// and hold a wanted channel are read; their message indexes give each
// message's time and offset, and a heap merges chunks in log-time order.
class IndexedCursor final : public MessageCursor {
 public:
  IndexedCursor(Readable& src, const ReaderOptions& ro, const BagSummary& summary, ReadOptions opts)
      : src_(src), ro_(ro), summary_(summary), opts_(std::move(opts)) {
    wanted_ = wanted_channels(summary_.channels, opts_.topics);
    for (const auto& ci : summary_.chunk_indexes) {
      if (ci.message_end_time < opts_.start_time || ci.message_start_time >= opts_.end_time) continue;
      if (!ci.message_index_offsets.empty()) {
        bool any = false;
        for (const auto& [id, off] : ci.message_index_offsets) any = any || wanted_.count(id) != 0;
        if (!any) continue;
      }
      chunks_.push_back(&ci);
    }
    if (opts_.order == ReadOrder::LogTime) {
      std::stable_sort(chunks_.begin(), chunks_.end(), [](const ChunkIndex* a, const ChunkIndex* b) {
        return a->message_start_time != b->message_start_time ? a->message_start_time < b->message_start_time
                                                              : a->chunk_start_offset < b->chunk_start_offset;
      });
    } else {
      std::stable_sort(chunks_.begin(), chunks_.end(), [](const ChunkIndex* a, const ChunkIndex* b) {
        return a->chunk_start_offset < b->chunk_start_offset;
      });
    }
  }

  bool next(MessageView& out) override {
    if (!status_.ok()) return false;
    while (true) {
      const bool have_more_chunks = next_chunk_ < chunks_.size();
      if (heap_.empty() && !have_more_chunks) return false;
      if (have_more_chunks && (heap_.empty() || (opts_.order == ReadOrder::LogTime &&
                                                 chunks_[next_chunk_]->message_start_time <= heap_.top().time))) {
        if (!load(next_chunk_++)) {
          if (!status_.ok()) return false;
        }
        continue;
      }
      const Entry e = heap_.top();
      heap_.pop();
      Loaded& chunk = loaded_[e.chunk];
      current_ = chunk.buffer;  // keeps the message bytes alive until the next call
      if (--chunk.remaining == 0) loaded_.erase(e.chunk);
      if (message_at(*current_, e, out)) return true;
      if (!status_.ok()) return false;
    }
  }

  const Status& status() const override { return status_; }
  const std::vector<ReadProblem>& problems() const override { return problems_; }

 private:
  struct Entry {
    Timestamp time = 0;     // log time (0 in file order)
    std::size_t chunk = 0;  // ordinal in chunks_
    std::uint64_t offset = 0;
    bool operator>(const Entry& o) const {
      if (time != o.time) return time > o.time;
      if (chunk != o.chunk) return chunk > o.chunk;
      return offset > o.offset;
    }
  };
  struct Loaded {
    std::shared_ptr<std::vector<std::uint8_t>> buffer;
    std::size_t remaining = 0;
    std::uint64_t file_offset = 0;
  };

  bool fail_chunk(std::uint64_t offset, Status s) {
    if (opts_.skip_bad_chunks && s.code != StatusCode::ReadFailed) {
      problems_.push_back(ReadProblem{offset, std::move(s)});
      return false;
    }
    status_ = std::move(s);
    return false;
  }

  bool load(std::size_t ordinal) {
    const ChunkIndex& ci = *chunks_[ordinal];
    const std::string w = fmt::format("{}: Chunk record at byte {}", src_.name(), ci.chunk_start_offset);
    const std::uint64_t size = src_.size();
    if (ci.chunk_start_offset > size || ci.chunk_length > size - ci.chunk_start_offset ||
        ci.chunk_length < kRecordPrefix) {
      return fail_chunk(ci.chunk_start_offset,
                        {StatusCode::InvalidRecord, fmt::format("{}: the chunk index places it at [{}, +{}) in a file "
                                                                "of {} bytes",
                                                                w, ci.chunk_start_offset, ci.chunk_length, size)});
    }
    if (ci.chunk_length > ro_.max_record_bytes) {
      return fail_chunk(ci.chunk_start_offset,
                        {StatusCode::LimitExceeded, fmt::format("{}: {} bytes, more than the limit of {}", w,
                                                                ci.chunk_length, ro_.max_record_bytes)});
    }
    record_.resize(static_cast<std::size_t>(ci.chunk_length));
    if (Status s = src_.read(ci.chunk_start_offset, record_); !s.ok()) return fail_chunk(ci.chunk_start_offset, s);
    std::uint64_t len;
    std::memcpy(&len, record_.data() + 1, 8);
    if (record_[0] != static_cast<std::uint8_t>(Opcode::Chunk) || len != ci.chunk_length - kRecordPrefix) {
      return fail_chunk(ci.chunk_start_offset,
                        {StatusCode::InvalidRecord,
                         fmt::format("{}: the chunk index points at a {} record of {} bytes, not a chunk of {}", w,
                                     opcode_name(record_[0]), len, ci.chunk_length - kRecordPrefix)});
    }
    Chunk chunk;
    if (Status s = parse(std::span(record_).subspan(kRecordPrefix), chunk, w); !s.ok())
      return fail_chunk(ci.chunk_start_offset, s);
    auto buffer = std::make_shared<std::vector<std::uint8_t>>();
    if (Status s =
            decompress(chunk.compression, chunk.records, chunk.uncompressed_size, ro_.max_record_bytes, *buffer, w);
        !s.ok())
      return fail_chunk(ci.chunk_start_offset, s);
    if (ro_.validate_crcs && chunk.uncompressed_crc != 0) {
      const std::uint32_t got = crc32(*buffer);
      if (got != chunk.uncompressed_crc) {
        return fail_chunk(ci.chunk_start_offset,
                          {StatusCode::CrcMismatch, fmt::format("{}: CRC of the uncompressed records 0x{:08x} != "
                                                                "stored 0x{:08x}",
                                                                w, got, chunk.uncompressed_crc)});
      }
    }

    std::vector<Entry> entries;
    if (!ci.message_index_offsets.empty() && ci.message_index_length > 0) {
      if (!index_entries(ordinal, ci, entries)) return false;
    } else if (!scan_entries(ordinal, ci, *buffer, entries)) {
      return false;
    }
    if (entries.empty()) return true;
    Loaded l;
    l.buffer = std::move(buffer);
    l.remaining = entries.size();
    l.file_offset = ci.chunk_start_offset;
    loaded_[ordinal] = std::move(l);
    for (const auto& e : entries) heap_.push(e);
    return true;
  }

  bool in_range(Timestamp t) const { return t >= opts_.start_time && t < opts_.end_time; }

  // Entries from the message index records after the chunk.
  bool index_entries(std::size_t ordinal, const ChunkIndex& ci, std::vector<Entry>& entries) {
    const std::uint64_t start = ci.chunk_start_offset + ci.chunk_length;
    const std::uint64_t size = src_.size();
    const std::string w =
        fmt::format("{}: message indexes of the chunk at byte {}", src_.name(), ci.chunk_start_offset);
    if (start > size || ci.message_index_length > size - start) {
      return fail_chunk(ci.chunk_start_offset,
                        {StatusCode::InvalidRecord, fmt::format("{}: [{}, +{}) lies outside the file of {} bytes", w,
                                                                start, ci.message_index_length, size)});
    }
    index_.resize(static_cast<std::size_t>(ci.message_index_length));
    if (Status s = src_.read(start, index_); !s.ok()) return fail_chunk(ci.chunk_start_offset, s);
    for (const auto& [id, off] : ci.message_index_offsets) {
      if (wanted_.count(id) == 0) continue;
      if (off < start || off - start > index_.size() || index_.size() - (off - start) < kRecordPrefix) {
        return fail_chunk(
            ci.chunk_start_offset,
            {StatusCode::InvalidRecord, fmt::format("{}: channel {}'s index offset {} is outside them", w, id, off)});
      }
      const std::size_t rel = static_cast<std::size_t>(off - start);
      std::uint64_t len;
      std::memcpy(&len, index_.data() + rel + 1, 8);
      if (index_[rel] != static_cast<std::uint8_t>(Opcode::MessageIndex) || len > index_.size() - rel - kRecordPrefix) {
        return fail_chunk(ci.chunk_start_offset,
                          {StatusCode::InvalidRecord,
                           fmt::format("{}: byte {} holds a {} record of {} bytes, not channel {}'s message index", w,
                                       off, opcode_name(index_[rel]), len, id)});
      }
      MessageIndex mi;
      if (Status s = parse(std::span(index_).subspan(rel + kRecordPrefix, len), mi, w); !s.ok())
        return fail_chunk(ci.chunk_start_offset, s);
      for (const auto& r : mi.records) {
        if (in_range(r.log_time)) {
          entries.push_back(Entry{opts_.order == ReadOrder::LogTime ? r.log_time : 0, ordinal, r.offset});
        }
      }
    }
    return true;
  }

  // Entries by walking the chunk's records (no message indexes).
  bool scan_entries(std::size_t ordinal, const ChunkIndex& ci, const std::vector<std::uint8_t>& buf,
                    std::vector<Entry>& entries) {
    std::size_t pos = 0;
    while (pos < buf.size()) {
      if (buf.size() - pos < kRecordPrefix) break;
      std::uint64_t len;
      std::memcpy(&len, buf.data() + pos + 1, 8);
      if (len > buf.size() - pos - kRecordPrefix) {
        return fail_chunk(ci.chunk_start_offset,
                          {StatusCode::InvalidRecord, fmt::format("{}: record at byte {} of the chunk at byte {} "
                                                                  "claims {} bytes, past the chunk's end",
                                                                  src_.name(), pos, ci.chunk_start_offset, len)});
      }
      if (buf[pos] == static_cast<std::uint8_t>(Opcode::Message) && len >= 22) {
        ChannelId id;
        Timestamp t;
        std::memcpy(&id, buf.data() + pos + 9, 2);
        std::memcpy(&t, buf.data() + pos + 15, 8);
        if (wanted_.count(id) != 0 && in_range(t)) {
          entries.push_back(Entry{opts_.order == ReadOrder::LogTime ? t : 0, ordinal, pos});
        }
      }
      pos += kRecordPrefix + static_cast<std::size_t>(len);
    }
    return true;
  }

  bool message_at(const std::vector<std::uint8_t>& buf, const Entry& e, MessageView& out) {
    const std::uint64_t file_offset = chunks_[e.chunk]->chunk_start_offset;
    const auto w = [&] {
      return fmt::format("{}: Message at byte {} of the chunk at byte {}", src_.name(), e.offset, file_offset);
    };
    if (e.offset > buf.size() || buf.size() - e.offset < kRecordPrefix ||
        buf[e.offset] != static_cast<std::uint8_t>(Opcode::Message)) {
      return fail_chunk(file_offset, {StatusCode::InvalidRecord,
                                      fmt::format("{}: the message index points at no Message record", w())});
    }
    std::uint64_t len;
    std::memcpy(&len, buf.data() + e.offset + 1, 8);
    if (len > buf.size() - e.offset - kRecordPrefix) {
      return fail_chunk(
          file_offset, {StatusCode::InvalidRecord, fmt::format("{}: claims {} bytes, past the chunk's end", w(), len)});
    }
    Message m;
    if (Status s = wire::parse_lazy(std::span(buf).subspan(e.offset + kRecordPrefix, len), m, w); !s.ok())
      return fail_chunk(file_offset, s);
    auto ch = summary_.channels.find(m.channel_id);
    if (ch == summary_.channels.end()) {
      return fail_chunk(file_offset, {StatusCode::InvalidRecord,
                                      fmt::format("{}: channel {} is not in the summary", w(), m.channel_id)});
    }
    if (wanted_.count(m.channel_id) == 0) return false;  // an index that lied about its channel: skip
    out.message = m;
    out.channel = &ch->second;
    auto sc = summary_.schemas.find(ch->second.schema_id);
    out.schema = sc == summary_.schemas.end() ? nullptr : &sc->second;
    return true;
  }

  Readable& src_;
  ReaderOptions ro_;
  const BagSummary& summary_;
  ReadOptions opts_;
  std::set<ChannelId> wanted_;
  std::vector<const ChunkIndex*> chunks_;
  std::size_t next_chunk_ = 0;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> heap_;
  std::map<std::size_t, Loaded> loaded_;
  std::shared_ptr<std::vector<std::uint8_t>> current_;
  std::vector<std::uint8_t> record_;
  std::vector<std::uint8_t> index_;
  Status status_;
  std::vector<ReadProblem> problems_;
};

}  // namespace

// ---------------------------------------------------------------------------- Reader

Reader::~Reader() = default;

std::string Reader::where(std::uint64_t offset, std::string_view what) const {
  return fmt::format("{}: {} at byte {}", source_->name(), what, offset);
}

Status Reader::open(const std::string& path, ReaderOptions options) {
  auto f = std::make_unique<FileReadable>();
  if (Status s = f->open(path); !s.ok()) return s;
  return open(std::move(f), options);
}

Status Reader::open(std::unique_ptr<Readable> source, ReaderOptions options) {
  if (!source) return {StatusCode::InvalidArgument, "reader opened with no source"};
  source_ = std::move(source);
  options_ = options;
  summary_ = {};
  has_summary_ = false;
  complete_ = false;
  const std::uint64_t size = source_->size();
  const std::string& name = source_->name();

  std::uint8_t head[8 + 9];
  if (size < sizeof(head)) {
    return {StatusCode::BadMagic, fmt::format("{}: {} bytes is too short for an MCAP file", name, size)};
  }
  if (Status s = source_->read(0, head); !s.ok()) return s;
  if (std::memcmp(head, kMagic.data(), 8) != 0) {
    return {StatusCode::BadMagic, fmt::format("{}: does not start with the MCAP magic (not an MCAP file?)", name)};
  }
  if (head[8] != static_cast<std::uint8_t>(Opcode::Header)) {
    return {StatusCode::InvalidRecord,
            fmt::format("{}: the first record is {}, not a Header", name, opcode_name(head[8]))};
  }
  std::uint64_t hlen;
  std::memcpy(&hlen, head + 9, 8);
  if (hlen > size - sizeof(head)) {
    return {StatusCode::Truncated, fmt::format("{}: the Header record claims {} bytes, the file has {} after it", name,
                                               hlen, size - sizeof(head))};
  }
  if (hlen > options_.max_record_bytes) {
    return {StatusCode::LimitExceeded, fmt::format("{}: Header record of {} bytes", name, hlen)};
  }
  std::vector<std::uint8_t> content(static_cast<std::size_t>(hlen));
  if (Status s = source_->read(sizeof(head), content); !s.ok()) return s;
  if (Status s = parse(content, summary_.header, where(8, "Header record")); !s.ok()) return s;
  data_start_ = sizeof(head) + hlen;

  // Footer: the last 29 + 8 bytes. Its absence is no error (a killed writer):
  // the file is then read linearly.
  if (size >= data_start_ + kFooterRecordSize + 8) {
    std::uint8_t tail[kFooterRecordSize + 8];
    const std::uint64_t footer_offset = size - sizeof(tail);
    if (Status s = source_->read(footer_offset, tail); !s.ok()) return s;
    if (std::memcmp(tail + kFooterRecordSize, kMagic.data(), 8) == 0) {
      std::uint64_t flen;
      std::memcpy(&flen, tail + 1, 8);
      if (tail[0] != static_cast<std::uint8_t>(Opcode::Footer) || flen != kFooterRecordSize - kRecordPrefix) {
        return {StatusCode::InvalidFooter,
                fmt::format("{}: the file ends with the magic but byte {} holds a {} record of {} bytes, not the "
                            "20-byte footer",
                            name, footer_offset, opcode_name(tail[0]), flen)};
      }
      Footer footer;
      if (Status s = parse(std::span<const std::uint8_t>(tail + kRecordPrefix, 20), footer,
                           where(footer_offset, "Footer record"));
          !s.ok())
        return s;
      complete_ = true;
      summary_.complete = true;
      if (footer.summary_start != 0 && !options_.ignore_summary) {
        if (Status s = open_summary(footer_offset, footer); !s.ok()) return s;
      }
    }
  }
  return {};
}

Status Reader::check_summary_place(std::uint64_t footer_offset, const Footer& footer) const {
  const std::string& name = source_->name();
  if (footer.summary_start < data_start_ || footer.summary_start > footer_offset) {
    return {StatusCode::InvalidFooter,
            fmt::format("{}: the footer puts the summary at byte {}, outside the file's [{}, {})", name,
                        footer.summary_start, data_start_, footer_offset)};
  }
  if (footer.summary_offset_start != 0 &&
      (footer.summary_offset_start < footer.summary_start || footer.summary_offset_start > footer_offset)) {
    return {StatusCode::InvalidFooter,
            fmt::format("{}: the footer puts the summary offsets at byte {}, outside the summary's [{}, {})", name,
                        footer.summary_offset_start, footer.summary_start, footer_offset)};
  }
  const std::uint64_t summary_len = footer_offset - footer.summary_start;
  if (summary_len > options_.max_record_bytes) {
    return {StatusCode::LimitExceeded, fmt::format("{}: summary section of {} bytes is over the limit of {}", name,
                                                   summary_len, options_.max_record_bytes)};
  }
  return {};
}

Status Reader::summary_record(std::uint8_t op, std::span<const std::uint8_t> content, const std::string& w,
                              const Footer& footer, bool& have_stats) {
  switch (static_cast<Opcode>(op)) {
    case Opcode::Schema: {
      Schema s;
      if (Status st = parse(content, s, w); !st.ok()) return st;
      if (s.id != 0) summary_.schemas[s.id] = std::move(s);
      return {};
    }
    case Opcode::Channel: {
      Channel c;
      if (Status st = parse(content, c, w); !st.ok()) return st;
      summary_.channels[c.id] = std::move(c);
      return {};
    }
    case Opcode::Statistics: have_stats = true; return parse(content, summary_.statistics, w);
    case Opcode::ChunkIndex: {
      ChunkIndex ci;
      if (Status st = parse(content, ci, w); !st.ok()) return st;
      if (ci.chunk_start_offset < data_start_ || ci.chunk_start_offset > footer.summary_start ||
          ci.chunk_length > footer.summary_start - ci.chunk_start_offset) {
        return {StatusCode::InvalidRecord,
                fmt::format("{}: places its chunk at [{}, +{}), outside the data section [{}, {})", w,
                            ci.chunk_start_offset, ci.chunk_length, data_start_, footer.summary_start)};
      }
      ++summary_.chunks_by_compression[ci.compression];
      summary_.chunk_indexes.push_back(std::move(ci));
      return {};
    }
    case Opcode::AttachmentIndex: {
      AttachmentIndex ai;
      if (Status st = parse(content, ai, w); !st.ok()) return st;
      summary_.attachment_indexes.push_back(std::move(ai));
      return {};
    }
    case Opcode::MetadataIndex: {
      MetadataIndex mi;
      if (Status st = parse(content, mi, w); !st.ok()) return st;
      summary_.metadata_indexes.push_back(std::move(mi));
      return {};
    }
    default: return {};  // unknown or unexpected records in the summary are skipped
  }
}

void Reader::statistics_from_chunk_indexes() {
  Statistics& st = summary_.statistics;
  st.schema_count = static_cast<std::uint16_t>(summary_.schemas.size());
  st.channel_count = static_cast<std::uint32_t>(summary_.channels.size());
  st.chunk_count = static_cast<std::uint32_t>(summary_.chunk_indexes.size());
  bool first = true;
  for (const auto& ci : summary_.chunk_indexes) {
    st.message_start_time = first ? ci.message_start_time : std::min(st.message_start_time, ci.message_start_time);
    st.message_end_time = first ? ci.message_end_time : std::max(st.message_end_time, ci.message_end_time);
    first = false;
  }
}

Status Reader::open_summary(std::uint64_t footer_offset, const Footer& footer) {
  const std::string& name = source_->name();
  if (Status s = check_summary_place(footer_offset, footer); !s.ok()) return s;
  const std::uint64_t summary_len = footer_offset - footer.summary_start;
  // The summary and the footer fields the CRC covers.
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(summary_len + kRecordPrefix + 16 + 4));
  if (Status s = source_->read(footer.summary_start, buf); !s.ok()) return s;
  if (options_.validate_crcs && footer.summary_crc != 0) {
    const std::uint32_t got = crc32(std::span(buf).first(buf.size() - 4));
    if (got != footer.summary_crc) {
      return {StatusCode::CrcMismatch, fmt::format("{}: summary section at byte {}: CRC 0x{:08x} != stored 0x{:08x}",
                                                   name, footer.summary_start, got, footer.summary_crc)};
    }
  }
  const std::uint64_t end =
      (footer.summary_offset_start != 0 ? footer.summary_offset_start : footer_offset) - footer.summary_start;
  std::uint64_t pos = 0;
  bool have_stats = false;
  while (pos < end) {
    const std::uint64_t at = footer.summary_start + pos;
    if (end - pos < kRecordPrefix) {
      return {StatusCode::InvalidRecord, fmt::format("{}: summary ends inside a record prefix at byte {}", name, at)};
    }
    const std::uint8_t op = buf[pos];
    std::uint64_t len;
    std::memcpy(&len, buf.data() + pos + 1, 8);
    if (len > end - pos - kRecordPrefix) {
      return {StatusCode::InvalidRecord,
              fmt::format("{}: {} record at byte {} claims {} bytes, past the end of the summary", name,
                          opcode_name(op), at, len)};
    }
    const auto content = std::span<const std::uint8_t>(buf).subspan(pos + kRecordPrefix, len);
    if (Status s = summary_record(op, content, where(at, opcode_name(op) + " record"), footer, have_stats); !s.ok()) {
      return s;
    }
    pos += kRecordPrefix + len;
  }
  if (!have_stats) statistics_from_chunk_indexes();  // no statistics record: what the chunk indexes tell
  has_summary_ = true;
  summary_.from_summary_section = true;
  return {};
}

Status Reader::scan() {
  if (!source_) return {StatusCode::NotOpen, "scan: reader is not open"};
  LinearReader lr(*source_, LinearReaderOptions{options_.validate_crcs, options_.max_record_bytes, true});
  BagSummary s;
  s.header = summary_.header;
  s.complete = complete_;
  bool first = true;
  LinearRecord r;
  while (lr.next(r)) {
    switch (r.kind) {
      case LinearRecord::Kind::Message: {
        auto& st = s.statistics;
        ++st.message_count;
        ++st.channel_message_counts[r.message.channel_id];
        st.message_start_time = first ? r.message.log_time : std::min(st.message_start_time, r.message.log_time);
        st.message_end_time = first ? r.message.log_time : std::max(st.message_end_time, r.message.log_time);
        first = false;
        break;
      }
      case LinearRecord::Kind::ChunkBegin:
        ++s.statistics.chunk_count;
        ++s.chunks_by_compression[r.chunk->compression];
        break;
      case LinearRecord::Kind::Attachment: ++s.statistics.attachment_count; break;
      case LinearRecord::Kind::Metadata: ++s.statistics.metadata_count; break;
      default: break;
    }
  }
  s.schemas = lr.schemas();
  s.channels = lr.channels();
  s.statistics.schema_count = static_cast<std::uint16_t>(s.schemas.size());
  s.statistics.channel_count = static_cast<std::uint32_t>(s.channels.size());
  summary_ = std::move(s);
  has_summary_ = false;
  if (!lr.status().ok()) return lr.status();
  if (!lr.problems().empty()) return lr.problems().front().status;
  return {};
}

std::unique_ptr<MessageCursor> Reader::read(const ReadOptions& options) {
  if (has_summary_ && !summary_.chunk_indexes.empty()) {
    return std::make_unique<IndexedCursor>(*source_, options_, summary_, options);
  }
  return std::make_unique<LinearCursor>(*source_, options_, options);
}

Status Reader::for_each(const ReadOptions& options, const std::function<bool(const MessageView&)>& fn) {
  if (!source_) return {StatusCode::NotOpen, "read: reader is not open"};
  auto cursor = read(options);
  MessageView v;
  while (cursor->next(v)) {
    if (!fn(v)) break;
  }
  return cursor->status();
}

Status Reader::read_attachment(const AttachmentIndex& index, std::vector<std::uint8_t>& data, Attachment& out) {
  if (!source_) return {StatusCode::NotOpen, "read_attachment: reader is not open"};
  const std::uint64_t size = source_->size();
  const std::string w = where(index.offset, "Attachment record");
  if (index.offset > size || index.length > size - index.offset || index.length < kRecordPrefix ||
      index.length > options_.max_record_bytes) {
    return {StatusCode::InvalidRecord,
            fmt::format("{}: index gives a length of {} in a file of {} bytes", w, index.length, size)};
  }
  data.resize(static_cast<std::size_t>(index.length));
  if (Status s = source_->read(index.offset, data); !s.ok()) return s;
  if (data[0] != static_cast<std::uint8_t>(Opcode::Attachment)) {
    return {StatusCode::InvalidRecord, fmt::format("{}: holds a {} record", w, opcode_name(data[0]))};
  }
  const auto content = std::span<const std::uint8_t>(data).subspan(kRecordPrefix);
  if (Status s = parse(content, out, w); !s.ok()) return s;
  if (options_.validate_crcs && out.crc != 0) {
    const std::uint32_t got = crc32(content.first(content.size() - 4));
    if (got != out.crc) {
      return {StatusCode::CrcMismatch, fmt::format("{}: CRC 0x{:08x} != stored 0x{:08x}", w, got, out.crc)};
    }
  }
  return {};
}

Status Reader::read_metadata(const MetadataIndex& index, Metadata& out) {
  if (!source_) return {StatusCode::NotOpen, "read_metadata: reader is not open"};
  const std::uint64_t size = source_->size();
  const std::string w = where(index.offset, "Metadata record");
  if (index.offset > size || index.length > size - index.offset || index.length < kRecordPrefix ||
      index.length > options_.max_record_bytes) {
    return {StatusCode::InvalidRecord,
            fmt::format("{}: index gives a length of {} in a file of {} bytes", w, index.length, size)};
  }
  std::vector<std::uint8_t> data(static_cast<std::size_t>(index.length));
  if (Status s = source_->read(index.offset, data); !s.ok()) return s;
  if (data[0] != static_cast<std::uint8_t>(Opcode::Metadata)) {
    return {StatusCode::InvalidRecord, fmt::format("{}: holds a {} record", w, opcode_name(data[0]))};
  }
  return parse(std::span<const std::uint8_t>(data).subspan(kRecordPrefix), out, w);
}

Status Reader::verify() {
  if (!source_) return {StatusCode::NotOpen, "verify: reader is not open"};
  LinearReader lr(*source_, LinearReaderOptions{true, options_.max_record_bytes, false});
  std::map<ChannelId, std::uint64_t> counts;
  std::uint64_t messages = 0;
  std::uint64_t chunks = 0;
  LinearRecord r;
  while (lr.next(r)) {
    if (r.kind == LinearRecord::Kind::Message) {
      ++messages;
      ++counts[r.message.channel_id];
    } else if (r.kind == LinearRecord::Kind::ChunkBegin) {
      ++chunks;
    }
  }
  if (!lr.status().ok()) return lr.status();
  const std::string& name = source_->name();
  if (!complete_) {
    return {StatusCode::Truncated, fmt::format("{}: no footer: the file is not complete", name)};
  }
  if (has_summary_) {
    const Statistics& st = summary_.statistics;
    if (st.message_count != 0 && st.message_count != messages) {
      return {StatusCode::InvalidRecord,
              fmt::format("{}: statistics count {} messages, the data holds {}", name, st.message_count, messages)};
    }
    for (const auto& [id, n] : st.channel_message_counts) {
      if (counts[id] != n) {
        return {StatusCode::InvalidRecord, fmt::format("{}: statistics count {} messages on channel {}, the data "
                                                       "holds {}",
                                                       name, n, id, counts[id])};
      }
    }
    if (!summary_.chunk_indexes.empty() && summary_.chunk_indexes.size() != chunks) {
      return {StatusCode::InvalidRecord,
              fmt::format("{}: {} chunk indexes for {} chunks", name, summary_.chunk_indexes.size(), chunks)};
    }
  }
  return {};
}

}  // namespace tinyline::bag
