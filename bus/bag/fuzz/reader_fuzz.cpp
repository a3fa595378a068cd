// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: arbitrary bytes through every reader path. Properties
// beyond "no crash, no sanitizer report": every failure carries a message,
// and whatever recover() writes is itself a valid, complete file.
#include <cstdint>
#include <cstdio>
#include <cstdlib>

#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/recover.hpp>
#include <tinyline/bag/ros2.hpp>

using namespace tinyline::bag;

namespace {

constexpr std::uint64_t kMaxRecord = 16ULL << 20;

[[noreturn]] void violated(const char* what, const Status& s) {
  std::fprintf(stderr, "property violated: %s: %s\n", what, s.str().c_str());
  std::abort();
}

void check_message(const Status& s, const char* what) {
  if (!s.ok() && s.message.empty()) violated(what, s);
}

void read_all(Reader& r, ReadOrder order, bool skip, std::vector<std::string> topics) {
  ReadOptions ro;
  ro.order = order;
  ro.skip_bad_chunks = skip;
  ro.topics = std::move(topics);
  ro.start_time = 0;
  auto cursor = r.read(ro);
  MessageView v;
  while (cursor->next(v)) {
    std::string why;
    // Decode what decodes: the CDR reader is part of what a bag reader exercises.
    if (const auto* ts = ros2::type_support_for(v.schema, *v.channel, &why)) {
      try {
        (void)ts->deserialize(v.message.data);
      } catch (const std::exception&) {}
    }
  }
  check_message(cursor->status(), "read");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  ReaderOptions opts;
  opts.max_record_bytes = kMaxRecord;
  {
    Reader r;
    const Status s = r.open(std::make_unique<MemoryReadable>(bytes), opts);
    check_message(s, "open");
    if (s.ok()) {
      read_all(r, ReadOrder::LogTime, false, {});
      read_all(r, ReadOrder::File, true, {});
      if (!r.channels().empty()) read_all(r, ReadOrder::LogTime, true, {r.channels().begin()->second.topic});
      std::vector<std::uint8_t> buf;
      for (const auto& ai : r.summary().attachment_indexes) {
        Attachment a;
        check_message(r.read_attachment(ai, buf, a), "attachment");
      }
      for (const auto& mi : r.summary().metadata_indexes) {
        Metadata m;
        check_message(r.read_metadata(mi, m), "metadata");
      }
      check_message(r.verify(), "verify");
      check_message(r.scan(), "scan");
    }
  }
  MemoryReadable src(bytes);
  RecoverOptions ro;
  ro.max_record_bytes = kMaxRecord;
  ro.writer.chunk_size_bytes = 4096;
  RecoverReport rep;
  MemoryWritable out;
  const Status rs = recover(src, out, ro, rep);
  check_message(rs, "recover");
  if (rs.ok()) {
    Reader again;
    const Status s = again.open(std::make_unique<MemoryReadable>(out.take()), opts);
    if (!s.ok()) violated("recovered file opens", s);
    if (!again.complete() || !again.has_summary()) violated("recovered file is complete", s);
    const Status v = again.verify();
    if (!v.ok()) violated("recovered file verifies", v);
    if (again.summary().statistics.message_count != rep.messages) violated("recovered count", Status{});
  }
  return 0;
}
