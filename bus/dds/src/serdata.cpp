// SPDX-License-Identifier: Apache-2.0
#include "serdata.hpp"

// iceoryx's C binding declares its functions without C linkage for C++.
extern "C" {
#include <iceoryx_binding_c/subscriber.h>
}
#include <dds/ddsc/dds_data_allocator.h>
#include <dds/ddsc/dds_loan_api.h>
#include <dds/ddsi/ddsi_shm_transport.h>
#include <dds/ddsi/q_radmin.h>
#include <fmt/format.h>

#include "probe.hpp"

#include <cstdio>
#include <cstring>
#include <new>

#if defined(__SANITIZE_THREAD__)
extern "C" void __tsan_acquire(void* addr);
extern "C" void __tsan_release(void* addr);

// Cyclone DDS (Debian's libddsc) is not instrumented: TSan sees its libc
// calls but not its atomics, so Cyclone's own buffer and mutex life cycles
// look racy. Each entry names a Cyclone-internal frame (or, for sd_free, the
// free our sertype does when Cyclone's reference count says so), never code
// of ours that shares data between our threads. Every binary linking
// tinyline::dds under TSan gets these (TSan asks for them at start).
extern "C" const char* __tsan_default_suppressions() {
  return "race:ddsrt_recvmsg\n"  // receive buffers reused by Cyclone
         "race:ddsrt_sendmsg\n"  // transmit buffers freed by Cyclone's gc thread
         "race:ddsrt_mutex_destroy\n"
         "race:ddsrt_mutex_lock\n"  // mutexes in memory Cyclone published with its atomics
         "race:sd_free\n"           // a sample freed on Cyclone's last unref
         "race_top:^strcmp$\n";  // Cyclone's gc frees a name another Cyclone thread compares (frames without symbols)
}
#endif

namespace tinyline::dds::detail {

void handing_over([[maybe_unused]] const ddsi_serdata* d) {
#if defined(__SANITIZE_THREAD__)
  __tsan_release(const_cast<ddsi_serdata*>(d));
#endif
}

void taking_over([[maybe_unused]] const ddsi_serdata* d) {
#if defined(__SANITIZE_THREAD__)
  __tsan_acquire(const_cast<ddsi_serdata*>(d));
#endif
}

namespace {

// A sample handed to dds_write / filled by dds_take is a byte vector holding
// encapsulated CDR. The bridge and the tools use dds_writecdr / dds_takecdr and
// never go through these; they exist so the generic DDS paths work too.
using Sample = std::vector<std::uint8_t>;

Serdata* new_serdata(const ddsi_sertype* type, ddsi_serdata_kind kind) {
  auto* d = new Serdata();
  ddsi_serdata_init(d, type, kind);
  return d;
}

const Sertype* sertype_of(const ddsi_sertype* t) { return static_cast<const Sertype*>(t); }

// XCDR: the two low bits of the encapsulation options count the padding bytes
// appended to reach a multiple of 4 (readers that ignore them lose nothing).
void pad(std::vector<std::uint8_t>& b) {
  const std::size_t n = (4 - b.size() % 4) % 4;
  b.insert(b.end(), n, 0);
  if (b.size() >= 4) b[3] = static_cast<std::uint8_t>((b[3] & ~0x3u) | n);
}

// ---------------------------------------------------------------- serdata ops

bool sd_eqkey(const ddsi_serdata*, const ddsi_serdata*) { return true; }  // keyless topics

std::uint32_t sd_get_size(const ddsi_serdata* d) { return static_cast<std::uint32_t>(serdata_bytes(d).size()); }

ddsi_serdata* sd_from_ser(const ddsi_sertype* type, ddsi_serdata_kind kind, const nn_rdata* frag, std::size_t size) {
  TL_DDS_PROBE(FromSer);
  if (size > sertype_of(type)->max_sample_bytes) return nullptr;  // dropped by Cyclone
  auto* d = new_serdata(type, kind);
  try {
    d->bytes.resize(size);
  } catch (const std::bad_alloc&) {
    delete d;
    return nullptr;
  }
  // Fragments may overlap; copy only what each adds beyond what we have.
  std::size_t have = 0;
  for (; frag != nullptr; frag = frag->nextfrag) {
    if (frag->maxp1 <= have) continue;
    if (frag->min > have || frag->maxp1 > size) {  // a hole or an overrun: refuse the sample
      delete d;
      return nullptr;
    }
    const unsigned char* payload = NN_RMSG_PAYLOADOFF(frag->rmsg, NN_RDATA_PAYLOAD_OFF(frag));
    std::memcpy(d->bytes.data() + have, payload + (have - frag->min), frag->maxp1 - have);
    have = frag->maxp1;
  }
  if (have != size) {
    delete d;
    return nullptr;
  }
  handing_over(d);
  return d;
}

ddsi_serdata* sd_from_ser_iov(const ddsi_sertype* type, ddsi_serdata_kind kind, ddsrt_msg_iovlen_t niov,
                              const ddsrt_iovec_t* iov, std::size_t size) {
  if (size > sertype_of(type)->max_sample_bytes) return nullptr;
  auto* d = new_serdata(type, kind);
  d->bytes.reserve(size);
  for (ddsrt_msg_iovlen_t i = 0; i < niov; ++i) {
    const auto* p = static_cast<const std::uint8_t*>(iov[i].iov_base);
    d->bytes.insert(d->bytes.end(), p, p + iov[i].iov_len);
  }
  if (d->bytes.size() != size) {
    delete d;
    return nullptr;
  }
  handing_over(d);
  return d;
}

ddsi_serdata* sd_from_keyhash(const ddsi_sertype* type, const ddsi_keyhash*) {
  return new_serdata(type, SDK_KEY);  // no key fields: the key is empty
}

ddsi_serdata* sd_from_sample(const ddsi_sertype* type, ddsi_serdata_kind kind, const void* sample) {
  auto* d = new_serdata(type, kind);
  if (kind == SDK_DATA) {
    d->bytes = *static_cast<const Sample*>(sample);
    pad(d->bytes);
  }
  return d;
}

ddsi_serdata* sd_to_untyped(const ddsi_serdata* d) {
  auto* u = new_serdata(d->type, SDK_KEY);
  u->type = nullptr;  // untyped by definition; the key is empty anyway
  return u;
}

void sd_to_ser(const ddsi_serdata* d, std::size_t off, std::size_t sz, void* buf) {
  taking_over(d);
  std::memcpy(buf, serdata_bytes(d).data() + off, sz);
}

ddsi_serdata* sd_to_ser_ref(const ddsi_serdata* d, std::size_t off, std::size_t sz, ddsrt_iovec_t* ref) {
  taking_over(d);
  ref->iov_base = const_cast<std::uint8_t*>(serdata_bytes(d).data() + off);
  ref->iov_len = static_cast<ddsrt_iov_len_t>(sz);
  return ddsi_serdata_ref(d);
}

void sd_to_ser_unref(ddsi_serdata* d, const ddsrt_iovec_t*) {
  handing_over(d);  // the transmit thread is done reading
  ddsi_serdata_unref(d);
}

bool sd_to_sample(const ddsi_serdata* d, void* sample, void**, void*) {
  taking_over(d);
  auto* out = static_cast<Sample*>(sample);
  const auto b = serdata_bytes(d);
  if (d->kind == SDK_DATA) {
    out->assign(b.begin(), b.end());
  } else {
    out->clear();
  }
  return true;
}

bool sd_untyped_to_sample(const ddsi_sertype*, const ddsi_serdata*, void* sample, void**, void*) {
  static_cast<Sample*>(sample)->clear();
  return true;
}

// A chunk loaned from a writer and never published (the write failed, or
// never happened) goes back to that writer's pool. A deleted writer's
// iceoryx publisher took its chunks back with it: nothing to give.
void release_unpublished(Serdata& s) {
  dds_data_allocator_t a;
  if (dds_data_allocator_init(s.loaned_from, &a) != DDS_RETCODE_OK) return;
  dds_data_allocator_free(&a, s.iox_chunk);
  dds_data_allocator_fini(&a);
  s.iox_chunk = nullptr;
}

void sd_free(ddsi_serdata* d) {
  taking_over(d);  // every thread that used it handed it over before its unref
  auto* s = static_cast<Serdata*>(d);
  // A chunk received through shared memory goes back to its subscriber; a
  // loaned one was handed to iceoryx by a write that published it (which
  // clears iox_chunk), or is still ours.
  if (s->iox_chunk != nullptr && s->iox_subscriber != nullptr) {
    free_iox_chunk(static_cast<iox_sub_t*>(s->iox_subscriber), &s->iox_chunk);
  } else if (s->iox_chunk != nullptr && s->loaned_from != 0) {
    release_unpublished(*s);
  }
  delete s;
}

// A sample from shared memory: its bytes stay in the chunk, which the sample
// holds until freed. Without a subscriber it is a loaned sample of a local
// write (dds_write with a loan, which we never do): copied, so it owns nothing.
ddsi_serdata* sd_from_iox(const ddsi_sertype* type, ddsi_serdata_kind kind, void* sub, void* buffer) {
  auto* d = new_serdata(type, kind);
  const iceoryx_header_t* h = iceoryx_header_from_chunk(buffer);
  if (sub == nullptr) {
    const auto* p = static_cast<const std::uint8_t*>(buffer);
    d->bytes.assign(p, p + h->data_size);
  } else {
    d->iox_chunk = buffer;
    d->iox_subscriber = sub;
    d->lost_before = iox_sub_has_lost_chunks(*static_cast<iox_sub_t*>(sub));
  }
  handing_over(d);
  return d;
}

std::uint32_t sd_sample_size(const ddsi_serdata* d) { return sd_get_size(d); }

std::size_t sd_print(const ddsi_sertype* type, const ddsi_serdata* d, char* buf, std::size_t size) {
  const auto* t = sertype_of(type);
  const int n =
      std::snprintf(buf, size, "%s: %zu bytes of CDR", t && t->type_name ? t->type_name : "?", serdata_bytes(d).size());
  return n < 0 ? 0 : static_cast<std::size_t>(n);
}

void sd_get_keyhash(const ddsi_serdata*, ddsi_keyhash* buf, bool) { std::memset(buf, 0, sizeof(*buf)); }

const ddsi_serdata_ops& serdata_ops() {
  static const ddsi_serdata_ops ops = [] {
    ddsi_serdata_ops o{};
    o.eqkey = sd_eqkey;
    o.get_size = sd_get_size;
    o.from_ser = sd_from_ser;
    o.from_ser_iov = sd_from_ser_iov;
    o.from_keyhash = sd_from_keyhash;
    o.from_sample = sd_from_sample;
    o.to_ser = sd_to_ser;
    o.to_ser_ref = sd_to_ser_ref;
    o.to_ser_unref = sd_to_ser_unref;
    o.to_sample = sd_to_sample;
    o.to_untyped = sd_to_untyped;
    o.untyped_to_sample = sd_untyped_to_sample;
    o.free = sd_free;
    o.print = sd_print;
    o.get_keyhash = sd_get_keyhash;
    o.get_sample_size = sd_sample_size;
    o.from_iox_buffer = sd_from_iox;
    return o;
  }();
  return ops;
}

// ---------------------------------------------------------------- sertype ops

void st_free(ddsi_sertype* t) {
  ddsi_sertype_fini(t);
  delete static_cast<Sertype*>(t);
}

void st_zero_samples(const ddsi_sertype*, void* samples, std::size_t count) {
  auto* s = static_cast<Sample*>(samples);
  for (std::size_t i = 0; i < count; ++i) s[i].clear();
}

void st_realloc_samples(void** ptrs, const ddsi_sertype*, void* old, std::size_t oldcount, std::size_t count) {
  auto* fresh = static_cast<Sample*>(::operator new(count * sizeof(Sample)));
  auto* prev = static_cast<Sample*>(old);
  const std::size_t keep = old != nullptr ? std::min(oldcount, count) : 0;
  for (std::size_t i = 0; i < keep; ++i) new (&fresh[i]) Sample(std::move(prev[i]));
  for (std::size_t i = keep; i < count; ++i) new (&fresh[i]) Sample();
  if (old != nullptr) {
    for (std::size_t i = 0; i < oldcount; ++i) prev[i].~Sample();
    ::operator delete(old);
  }
  if (ptrs != nullptr) {
    for (std::size_t i = 0; i < count; ++i) ptrs[i] = &fresh[i];
  }
}

void st_free_samples(const ddsi_sertype*, void** ptrs, std::size_t count, dds_free_op_t op) {
  if (count == 0 || ptrs == nullptr) return;
  if (op & DDS_FREE_CONTENTS_BIT) {
    for (std::size_t i = 0; i < count; ++i) Sample().swap(*static_cast<Sample*>(ptrs[i]));
  }
  if (op & DDS_FREE_ALL_BIT) {  // the block came from st_realloc_samples
    for (std::size_t i = 0; i < count; ++i) static_cast<Sample*>(ptrs[i])->~Sample();
    ::operator delete(ptrs[0]);
  }
}

// All our sertypes of one type name describe the same bytes.
bool st_equal(const ddsi_sertype*, const ddsi_sertype*) { return true; }
std::uint32_t st_hash(const ddsi_sertype*) { return 0x7111e5u; }

std::size_t st_get_serialized_size(const ddsi_sertype*, const void* sample) {
  const auto n = static_cast<const Sample*>(sample)->size();
  return n + (4 - n % 4) % 4;
}

bool st_serialize_into(const ddsi_sertype*, const void* sample, void* dst, std::size_t dst_size) {
  Sample b = *static_cast<const Sample*>(sample);
  pad(b);
  if (b.size() > dst_size) return false;
  std::memcpy(dst, b.data(), b.size());
  return true;
}

const ddsi_sertype_ops& sertype_ops() {
  static const ddsi_sertype_ops ops = [] {
    ddsi_sertype_ops o{};
    o.version = ddsi_sertype_v0;
    o.free = st_free;
    o.zero_samples = st_zero_samples;
    o.realloc_samples = st_realloc_samples;
    o.free_samples = st_free_samples;
    o.equal = st_equal;
    o.hash = st_hash;
    o.get_serialized_size = st_get_serialized_size;
    o.serialize_into = st_serialize_into;
    return o;
  }();
  return ops;
}

}  // namespace

ddsi_sertype* make_sertype(const std::string& dds_type_name, const msg::TypeSupport* type,
                           std::size_t max_sample_bytes) {
  auto* st = new Sertype();
  ddsi_sertype_init_flags(st, dds_type_name.c_str(), &sertype_ops(), &serdata_ops(),
                          DDSI_SERTYPE_FLAG_TOPICKIND_NO_KEY);
  // ROS 2 speaks XCDR1; a writer that can only do XCDR2 is refused at matching.
  st->allowed_data_representation = DDS_DATA_REPRESENTATION_FLAG_XCDR1;
  st->type = type;
  st->max_sample_bytes = max_sample_bytes;
  return st;
}

ddsi_serdata* make_serdata(const ddsi_sertype* type, std::vector<std::uint8_t>&& encapsulated_cdr) {
  auto* d = new_serdata(type, SDK_DATA);
  d->bytes = std::move(encapsulated_cdr);
  pad(d->bytes);
  handing_over(d);  // to dds_writecdr
  return d;
}

ddsi_serdata* make_serdata_for(std::int32_t writer, bool shared_memory, const ddsi_sertype* type,
                               std::vector<std::uint8_t>&& encapsulated_cdr, std::string& error) {
  auto* d = new_serdata(type, SDK_DATA);
  d->bytes = std::move(encapsulated_cdr);
  pad(d->bytes);
  if (shared_memory) {
    void* chunk = nullptr;
    const dds_return_t rc = dds_loan_shared_memory_buffer(writer, d->bytes.size(), &chunk);
    if (rc != DDS_RETCODE_OK || chunk == nullptr) {
      error = fmt::format(
          "no shared-memory chunk of {} bytes ({}): RouDi's memory pools are used up or have "
          "no chunk that large",
          d->bytes.size(), dds_strretcode(rc));
      delete d;
      return nullptr;
    }
    std::memcpy(chunk, d->bytes.data(), d->bytes.size());
    iceoryx_header_t* h = iceoryx_header_from_chunk(chunk);
    h->data_size = static_cast<std::uint32_t>(d->bytes.size());
    h->shm_data_state = IOX_CHUNK_CONTAINS_SERIALIZED_DATA;
    d->iox_chunk = chunk;  // dds_writecdr publishes it (and takes it off the sample)
    d->loaned_from = writer;
  }
  handing_over(d);
  return d;
}

dds_return_t write_serdata(dds_entity_t writer, ddsi_serdata* d) {
  handing_over(d);
  const dds_return_t rc = dds_writecdr(writer, d);
  // dds_writer_lock's failures: the sample never reached Cyclone.
  if (rc == DDS_RETCODE_BAD_PARAMETER || rc == DDS_RETCODE_ALREADY_DELETED || rc == DDS_RETCODE_ILLEGAL_OPERATION) {
    ddsi_serdata_unref(d);
  }
  return rc;
}

std::span<const std::uint8_t> serdata_bytes(const ddsi_serdata* d) {
  const auto* s = static_cast<const Serdata*>(d);
  if (s->bytes.empty() && s->iox_chunk != nullptr && s->iox_subscriber != nullptr) {
    return {static_cast<const std::uint8_t*>(s->iox_chunk), iceoryx_header_from_chunk(s->iox_chunk)->data_size};
  }
  return {s->bytes.data(), s->bytes.size()};
}

bool serdata_lost_before(const ddsi_serdata* d) { return static_cast<const Serdata*>(d)->lost_before; }

}  // namespace tinyline::dds::detail
