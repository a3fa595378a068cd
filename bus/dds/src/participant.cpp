// SPDX-License-Identifier: Apache-2.0
#include <tinyline/dds/participant.hpp>

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <map>
#include <mutex>

#include <fmt/format.h>

#include <tinyline/dds/naming.hpp>

#include "entities.hpp"
#include "serdata.hpp"

extern char* program_invocation_short_name;  // glibc

namespace tinyline::dds {

namespace detail {

void fail(const std::string& what, dds_return_t rc) { throw DdsError(fmt::format("{}: {}", what, dds_strretcode(rc))); }

void fill_qos(Qos& out, const EndpointQos& q, bool reader, const Identity& who, const msg::TypeSupport* type) {
  dds_qset_reliability(out.q, q.reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT,
                       q.max_blocking.count());
  dds_qset_durability(out.q, q.transient_local ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE);
  const dds_history_kind_t kind = q.keep_all ? DDS_HISTORY_KEEP_ALL : DDS_HISTORY_KEEP_LAST;
  const int32_t depth = q.keep_all ? DDS_LENGTH_UNLIMITED : std::max(1, q.depth);
  dds_qset_history(out.q, kind, depth);
  // Cyclone keeps for late joiners what the durability service's history
  // says (depth 1 unless set), not the writer's history: as rmw_cyclonedds does.
  if (q.transient_local) {
    dds_qset_durability_service(out.q, 0, kind, depth, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED,
                                DDS_LENGTH_UNLIMITED);
  }
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(out.q, 1, &xcdr1);
  if (reader && !q.accept_local) dds_qset_ignorelocal(out.q, DDS_IGNORELOCAL_PARTICIPANT);
  std::string ud = type != nullptr && !type->type_hash.empty() ? fmt::format("typehash={};", type->type_hash) : "";
  ud += who.to_user_data();
  dds_qset_userdata(out.q, ud.data(), ud.size());
}

EndpointQos read_qos(const dds_qos_t* q) {
  EndpointQos e;
  if (q == nullptr) return e;
  dds_reliability_kind_t rk;
  dds_duration_t block = 0;
  if (dds_qget_reliability(q, &rk, &block)) {
    e.reliable = rk == DDS_RELIABILITY_RELIABLE;
    e.max_blocking = std::chrono::nanoseconds(block);
  }
  dds_durability_kind_t dk;
  if (dds_qget_durability(q, &dk)) e.transient_local = dk != DDS_DURABILITY_VOLATILE;
  dds_history_kind_t hk;
  int32_t depth = 1;
  if (dds_qget_history(q, &hk, &depth)) {
    e.keep_all = hk == DDS_HISTORY_KEEP_ALL;
    e.depth = e.keep_all ? 0 : depth;
  }
  return e;
}

Identity read_identity(const dds_qos_t* q) {
  void* v = nullptr;
  std::size_t n = 0;
  if (q == nullptr || !dds_qget_userdata(q, &v, &n) || v == nullptr) return {};
  Identity id = Identity::parse(std::string_view(static_cast<const char*>(v), n));
  dds_free(v);
  return id;
}

TopicHandle create_topic(dds_entity_t participant, const std::string& dds_topic, const std::string& dds_type,
                         const msg::TypeSupport* type, std::size_t max_sample_bytes) {
  ddsi_sertype* st = make_sertype(dds_type, type, max_sample_bytes);
  const dds_entity_t t = dds_create_topic_sertype(participant, dds_topic.c_str(), &st, nullptr, nullptr, nullptr);
  if (t < 0) {
    ddsi_sertype_free(st);  // not handed over on failure
    fail(fmt::format("cannot create DDS topic '{}' with type '{}' (another type on the same topic?)", dds_topic,
                     dds_type),
         t);
  }
  return {t, st};
}

const char* policy_name(std::uint32_t id) {
  switch (id) {
    case DDS_DURABILITY_QOS_POLICY_ID: return "durability (volatile vs transient local)";
    case DDS_RELIABILITY_QOS_POLICY_ID: return "reliability (best effort vs reliable)";
    case DDS_DEADLINE_QOS_POLICY_ID: return "deadline";
    case DDS_LIVELINESS_QOS_POLICY_ID: return "liveliness";
    case DDS_OWNERSHIP_QOS_POLICY_ID: return "ownership";
    case DDS_PRESENTATION_QOS_POLICY_ID: return "presentation";
    case DDS_DESTINATIONORDER_QOS_POLICY_ID: return "destination order";
    case DDS_LATENCYBUDGET_QOS_POLICY_ID: return "latency budget";
    case DDS_PARTITION_QOS_POLICY_ID: return "partition";
    case DDS_DATA_REPRESENTATION_QOS_POLICY_ID: return "data representation (XCDR1 vs XCDR2)";
    case DDS_TYPE_CONSISTENCY_ENFORCEMENT_QOS_POLICY_ID: return "type consistency";
    default: return "a QoS policy";
  }
}

std::string guid_hex(const dds_guid_t& g) {
  std::string s;
  for (std::size_t i = 0; i < sizeof(g.v); ++i) s += fmt::format("{:02x}", g.v[i]);
  return s;
}

}  // namespace detail

using detail::fail;

// ---------------------------------------------------------------------------- Identity, EndpointQos

std::string Identity::describe() const {
  if (!known()) return "a participant that is not tinyline";
  return fmt::format("process '{}' (pid {} on {})", process, pid, host);
}

std::string Identity::to_user_data() const { return fmt::format("process={};pid={};host={};", process, pid, host); }

Identity Identity::parse(std::string_view ud) {
  Identity id;
  while (!ud.empty()) {
    const auto semi = ud.find(';');
    const std::string_view kv = ud.substr(0, semi);
    ud = semi == std::string_view::npos ? std::string_view() : ud.substr(semi + 1);
    const auto eq = kv.find('=');
    if (eq == std::string_view::npos) continue;
    const auto key = kv.substr(0, eq);
    const auto val = kv.substr(eq + 1);
    if (key == "process") {
      id.process = std::string(val);
    } else if (key == "pid") {
      id.pid = std::strtol(std::string(val).c_str(), nullptr, 10);
    } else if (key == "host") {
      id.host = std::string(val);
    } else if (key == "typehash") {
      id.type_hash = std::string(val);
    }
  }
  return id;
}

std::string EndpointQos::describe() const {
  return fmt::format("{}, {}, {}", reliable ? "reliable" : "best effort",
                     transient_local ? "transient local" : "volatile",
                     keep_all ? std::string("keep all") : fmt::format("keep last {}", depth));
}

// ---------------------------------------------------------------------------- Participant

namespace {

// Cyclone keeps one configuration per domain and process; participants of the
// same domain share it. Counted so the domain goes when its last user does.
struct DomainUse {
  dds_entity_t domain = 0;  // 0: created outside tinyline, not ours to delete
  std::string config;
  int users = 0;
};
std::mutex g_domains_mu;
std::map<int, DomainUse> g_domains;

std::string host_name() {
  char buf[256] = {0};
  if (gethostname(buf, sizeof(buf) - 1) != 0) return "unknown-host";
  return buf;
}

}  // namespace

Participant::Participant(Settings settings) : settings_(std::move(settings)) {
  check_domain_id(settings_.domain_id, "Settings.domain_id");
  // Only with a RouDi there: without one Cyclone would wait and then abort.
  shared_memory_ = settings_.shared_memory && roudi_running();
  std::string config = settings_.effective_config();
  if (shared_memory_) config = config.empty() ? shared_memory_config() : config + "," + shared_memory_config();
  identity_.process =
      settings_.process_name.empty() ? std::string(program_invocation_short_name) : settings_.process_name;
  identity_.pid = static_cast<long>(getpid());
  identity_.host = host_name();
  {
    std::lock_guard lk(g_domains_mu);
    auto it = g_domains.find(settings_.domain_id);
    if (it == g_domains.end()) {
      const dds_entity_t d = dds_create_domain(static_cast<dds_domainid_t>(settings_.domain_id), config.c_str());
      if (d < 0 && d != DDS_RETCODE_PRECONDITION_NOT_MET) {
        fail(fmt::format("cannot start DDS domain {} with configuration '{}' (Cyclone prints the offending element "
                         "above; see docs/dds.md)",
                         settings_.domain_id, config),
             d);
      }
      it = g_domains.emplace(settings_.domain_id, DomainUse{d < 0 ? 0 : d, config, 0}).first;
    } else if (it->second.config != config) {
      throw DdsError(
          fmt::format("DDS domain {} already runs in this process with another configuration", settings_.domain_id));
    }
    ++it->second.users;
  }
  detail::Qos q;
  // ROS 2 participants carry "enclave=/;"; ours add who we are.
  const std::string ud = "enclave=/;" + identity_.to_user_data();
  dds_qset_userdata(q.q, ud.data(), ud.size());
  participant_ = dds_create_participant(static_cast<dds_domainid_t>(settings_.domain_id), q.q, nullptr);
  if (participant_ < 0) {
    const dds_return_t rc = participant_;
    participant_ = 0;
    {
      std::lock_guard lk(g_domains_mu);
      auto it = g_domains.find(settings_.domain_id);
      if (--it->second.users == 0) {
        if (it->second.domain > 0) dds_delete(it->second.domain);
        g_domains.erase(it);
      }
    }
    fail(fmt::format("cannot create a DDS participant on domain {}", settings_.domain_id), rc);
  }
}

Participant::~Participant() {
  if (participant_ > 0) dds_delete(participant_);
  std::lock_guard lk(g_domains_mu);
  auto it = g_domains.find(settings_.domain_id);
  if (it != g_domains.end() && --it->second.users == 0) {
    if (it->second.domain > 0) dds_delete(it->second.domain);
    g_domains.erase(it);
  }
}

// ---------------------------------------------------------------------------- RawReader

RawReader::RawReader(Participant& p, const std::string& dds_topic, const std::string& dds_type,
                     const EndpointQos& qos) {
  topic_ = detail::create_topic(p.handle(), dds_topic, dds_type, find_type_by_dds_name(dds_type),
                                p.settings().max_sample_bytes)
               .topic;
  detail::Qos q;
  detail::fill_qos(q, qos, true, p.identity(), find_type_by_dds_name(dds_type));
  reader_ = dds_create_reader(p.handle(), topic_, q.q, nullptr);
  if (reader_ < 0) {
    const auto rc = reader_;
    dds_delete(topic_);
    fail("cannot create a DDS reader on '" + dds_topic + "'", rc);
  }
  cond_ = dds_create_readcondition(reader_, DDS_ANY_STATE);
  waitset_ = dds_create_waitset(p.handle());
  dds_waitset_attach(waitset_, cond_, 0);
}

RawReader::~RawReader() {
  dds_delete(waitset_);
  dds_delete(reader_);
  dds_delete(topic_);
}

std::size_t RawReader::take(std::chrono::nanoseconds timeout, const std::function<void(const RawSample&)>& fn) {
  dds_waitset_wait(waitset_, nullptr, 0, timeout.count());
  std::size_t n = 0;
  for (;;) {
    ddsi_serdata* sd = nullptr;
    dds_sample_info_t info;
    if (dds_takecdr(reader_, &sd, 1, &info, DDS_ANY_STATE) <= 0) break;
    detail::taking_over(sd);
    if (info.valid_data) {
      RawSample s;
      s.cdr = detail::serdata_bytes(sd);
      s.source_time_ns = info.source_timestamp;
      s.publication = info.publication_handle;
      ++n;
      try {
        fn(s);
      } catch (...) {
        detail::handing_over(sd);
        ddsi_serdata_unref(sd);
        throw;
      }
    }
    detail::handing_over(sd);
    ddsi_serdata_unref(sd);
  }
  return n;
}

std::size_t RawReader::matched_writers() const {
  dds_subscription_matched_status_t st;
  if (dds_get_subscription_matched_status(reader_, &st) < 0) return 0;
  return st.current_count;
}

std::vector<Identity> RawReader::matched_writer_identities() const {
  std::vector<dds_instance_handle_t> hs(64);
  const dds_return_t n = dds_get_matched_publications(reader_, hs.data(), hs.size());
  std::vector<Identity> out;
  for (dds_return_t i = 0; i < n && i < static_cast<dds_return_t>(hs.size()); ++i) {
    if (dds_builtintopic_endpoint_t* e = dds_get_matched_publication_data(reader_, hs[static_cast<std::size_t>(i)])) {
      out.push_back(detail::read_identity(e->qos));
      dds_builtintopic_free_endpoint(e);
    }
  }
  return out;
}

// ---------------------------------------------------------------------------- RawWriter

RawWriter::RawWriter(Participant& p, const std::string& dds_topic, const std::string& dds_type,
                     const EndpointQos& qos) {
  const auto th = detail::create_topic(p.handle(), dds_topic, dds_type, find_type_by_dds_name(dds_type),
                                       p.settings().max_sample_bytes);
  topic_ = th.topic;
  sertype_ = th.sertype;
  participant_ = p.handle();
  detail::Qos q;
  detail::fill_qos(q, qos, false, p.identity(), find_type_by_dds_name(dds_type));
  writer_ = dds_create_writer(p.handle(), topic_, q.q, nullptr);
  if (writer_ < 0) {
    const auto rc = writer_;
    dds_delete(topic_);
    fail("cannot create a DDS writer on '" + dds_topic + "'", rc);
  }
}

RawWriter::~RawWriter() {
  dds_delete(writer_);
  dds_delete(topic_);
}

void RawWriter::write(std::span<const std::uint8_t> cdr) {
  ddsi_serdata* sd = detail::make_serdata(static_cast<const ddsi_sertype*>(sertype_),
                                          std::vector<std::uint8_t>(cdr.begin(), cdr.end()));
  if (const auto rc = detail::write_serdata(writer_, sd); rc < 0) fail("DDS write failed", rc);
}

std::size_t RawWriter::matched_readers() const {
  dds_publication_matched_status_t st;
  if (dds_get_publication_matched_status(writer_, &st) < 0) return 0;
  return st.current_count;
}

bool RawWriter::wait_for_readers(std::size_t n, std::chrono::nanoseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  // Cyclone has no blocking "wait for matched"; a waitset on the status does it.
  const dds_entity_t ws = dds_create_waitset(participant_);
  dds_set_status_mask(writer_, DDS_PUBLICATION_MATCHED_STATUS);
  dds_waitset_attach(ws, writer_, 0);
  bool ok = false;
  for (;;) {
    if (matched_readers() >= n) {
      ok = true;
      break;
    }
    const auto left = deadline - std::chrono::steady_clock::now();
    if (left <= std::chrono::nanoseconds(0)) break;
    dds_waitset_wait(ws, nullptr, 0, std::chrono::duration_cast<std::chrono::nanoseconds>(left).count());
    dds_publication_matched_status_t st;
    dds_get_publication_matched_status(writer_, &st);  // resets the trigger
  }
  dds_delete(ws);
  return ok;
}

// ---------------------------------------------------------------------------- Discovery

Discovery::Discovery(Participant& p) {
  self_ = p.handle();
  publications_ = dds_create_reader(p.handle(), DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr);
  subscriptions_ = dds_create_reader(p.handle(), DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, nullptr, nullptr);
  if (publications_ < 0) fail("cannot read DDS discovery data", publications_);
  if (subscriptions_ < 0) fail("cannot read DDS discovery data", subscriptions_);
}

Discovery::~Discovery() {
  dds_delete(publications_);
  dds_delete(subscriptions_);
}

std::vector<DiscoveredEndpoint> Discovery::snapshot() const {
  dds_guid_t self{};
  dds_get_guid(self_, &self);
  const std::string self_hex = detail::guid_hex(self);
  std::vector<DiscoveredEndpoint> out;
  for (const dds_entity_t r : {publications_, subscriptions_}) {
    constexpr std::size_t kMax = 4096;
    std::vector<void*> buf(kMax, nullptr);
    std::vector<dds_sample_info_t> info(kMax);
    const dds_return_t n = dds_read_mask(r, buf.data(), info.data(), kMax, kMax,
                                         DDS_ANY_SAMPLE_STATE | DDS_ANY_VIEW_STATE | DDS_ALIVE_INSTANCE_STATE);
    for (dds_return_t i = 0; i < n; ++i) {
      if (!info[static_cast<std::size_t>(i)].valid_data) continue;
      const auto* e = static_cast<const dds_builtintopic_endpoint_t*>(buf[static_cast<std::size_t>(i)]);
      DiscoveredEndpoint d;
      d.writer = r == publications_;
      d.participant = detail::guid_hex(e->participant_key);
      if (d.participant == self_hex) continue;
      d.dds_topic = e->topic_name ? e->topic_name : "";
      d.dds_type = e->type_name ? e->type_name : "";
      d.topic = ros_topic_name(d.dds_topic);
      d.type = ros_type_name(d.dds_type);
      d.qos = detail::read_qos(e->qos);
      d.owner = detail::read_identity(e->qos);
      out.push_back(std::move(d));
    }
    if (n > 0) dds_return_loan(r, buf.data(), n);
  }
  std::sort(out.begin(), out.end(), [](const DiscoveredEndpoint& a, const DiscoveredEndpoint& b) {
    return std::tie(a.dds_topic, a.writer, a.participant) < std::tie(b.dds_topic, b.writer, b.participant);
  });
  return out;
}

std::vector<DiscoveredEndpoint> Discovery::settle(std::chrono::milliseconds settle,
                                                  std::chrono::milliseconds timeout) const {
  using SC = std::chrono::steady_clock;
  const auto start = SC::now();
  auto last = snapshot();
  auto last_change = start;
  // New discovery data makes the not-yet-read conditions trigger.
  const dds_entity_t ws = dds_create_waitset(self_);
  const dds_entity_t c1 = dds_create_readcondition(publications_, DDS_NOT_READ_SAMPLE_STATE);
  const dds_entity_t c2 = dds_create_readcondition(subscriptions_, DDS_NOT_READ_SAMPLE_STATE);
  dds_waitset_attach(ws, c1, 0);
  dds_waitset_attach(ws, c2, 0);
  auto key = [](const std::vector<DiscoveredEndpoint>& v) {
    std::string k;
    for (const auto& e : v) k += e.dds_topic + (e.writer ? "W" : "R") + e.participant + ";";
    return k;
  };
  // Nothing found yet is not settled: discovery may simply be slow (a loaded
  // machine); only the timeout ends a wait that finds nothing.
  while (SC::now() - start < timeout && (SC::now() - last_change < settle || last.empty())) {
    dds_waitset_wait(ws, nullptr, 0, DDS_MSECS(20));
    auto now = snapshot();
    if (key(now) != key(last)) {
      last = std::move(now);
      last_change = SC::now();
    }
  }
  dds_delete(c1);
  dds_delete(c2);
  dds_delete(ws);
  return last;
}

std::vector<DiscoveredEndpoint> Discovery::wait_for(
    const std::function<bool(const std::vector<DiscoveredEndpoint>&)>& pred, std::chrono::milliseconds timeout) const {
  using SC = std::chrono::steady_clock;
  const auto deadline = SC::now() + timeout;
  const dds_entity_t ws = dds_create_waitset(self_);
  const dds_entity_t c1 = dds_create_readcondition(publications_, DDS_NOT_READ_SAMPLE_STATE);
  const dds_entity_t c2 = dds_create_readcondition(subscriptions_, DDS_NOT_READ_SAMPLE_STATE);
  dds_waitset_attach(ws, c1, 0);
  dds_waitset_attach(ws, c2, 0);
  auto snap = snapshot();
  while (!pred(snap)) {
    const auto left = deadline - SC::now();
    if (left <= SC::duration::zero()) break;
    // Bounded so endpoints that vanish (no new sample to trigger on) are noticed.
    dds_waitset_wait(
        ws, nullptr, 0,
        std::min<std::int64_t>(DDS_MSECS(200), std::chrono::duration_cast<std::chrono::nanoseconds>(left).count()));
    snap = snapshot();
  }
  dds_delete(c1);
  dds_delete(c2);
  dds_delete(ws);
  return snap;
}

}  // namespace tinyline::dds
