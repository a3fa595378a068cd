// SPDX-License-Identifier: Apache-2.0
#include <tinyline/dds/bridge.hpp>

#include <algorithm>
#include <map>
#include <optional>

#include <dds/ddsc/dds_loan_api.h>
#include <fmt/format.h>

#include <tinyline/dds/naming.hpp>

#include "entities.hpp"
#include "probe.hpp"
#include "ros_graph.hpp"
#include "serdata.hpp"

namespace tinyline::dds {

using detail::fail;

bool TopicSelection::selects(const std::string& topic) const {
  return all || std::find(topics.begin(), topics.end(), topic) != topics.end();
}

namespace {

thread_local bool t_in_sync = false;  // the bridge's own endpoints must not re-enter sync_topic
// True inside our listener (Cyclone's receive thread, or a writer's thread
// delivering to a reader of this process): a change of endpoints seen there
// must not make us replace the very reader whose listener it runs in
// (deleting it waits for that listener).
thread_local bool t_in_listener = false;

std::atomic<std::uint32_t> g_next_origin{0xdd500001u};

bool same(const EndpointQos& a, const EndpointQos& b) {
  return a.reliable == b.reliable && a.transient_local == b.transient_local && a.keep_all == b.keep_all &&
         a.depth == b.depth;
}

/// Logs the first failure of a kind and then every 100th, so a broken peer
/// cannot flood the log.
bool worth_logging(std::uint64_t count) { return count == 1 || count % 100 == 0; }

constexpr int kEndpointBatch = 32;

}  // namespace

EndpointQos offered_qos(const std::vector<bus::QoS>& pubs) {
  EndpointQos e;
  // Every writer offers reliable: under DDS's request/offered rule a reliable
  // offer serves best-effort readers too (they get best-effort delivery), and
  // it costs nothing until a reliable reader matches. So best effort stays the
  // subscriber's choice, as in one process, where a sensor_data() publisher
  // reaches a default subscriber: splitting a graph must not cut that edge.
  e.reliable = true;
  e.depth = 1;
  e.max_blocking = std::chrono::nanoseconds(0);
  for (const auto& q : pubs) {
    e.transient_local |= q.transient_local;
    e.keep_all |= q.history == bus::QoS::History::Reliable;
    e.depth = std::max(e.depth, static_cast<int>(q.depth));
    e.max_blocking = std::max(e.max_blocking, std::chrono::duration_cast<std::chrono::nanoseconds>(q.max_block));
  }
  return e;
}

EndpointQos requested_qos(const std::vector<bus::QoS>& subs) {
  EndpointQos e;
  e.reliable = true;
  e.transient_local = true;
  e.depth = 1;
  for (const auto& q : subs) {
    e.reliable &= !q.best_effort;
    e.transient_local &= q.transient_local;
    e.keep_all |= q.history == bus::QoS::History::Reliable;
    e.depth = std::max(e.depth, static_cast<int>(q.depth));
  }
  return e;
}

std::string incompatibility(const EndpointQos& offered, const EndpointQos& requested) {
  // Request-offered: a reader gets nothing from a writer that offers less.
  std::string why;
  if (requested.reliable && !offered.reliable) why = "the publishers are best effort, the subscribers require reliable";
  if (requested.transient_local && !offered.transient_local) {
    why += std::string(why.empty() ? "" : "; ") +
           "the subscribers require transient local (latched), the publishers are volatile";
  }
  return why;
}

struct Bridge::Link {
  Bridge* bridge = nullptr;
  std::string name;
  const msg::TypeSupport* type = nullptr;
  detail::TopicHandle topic;
  // Written by sync_topic (serialised by sync_mu_), read by callbacks.
  std::atomic<dds_entity_t> writer{0};
  std::atomic<dds_entity_t> reader{0};
  std::atomic<bool> writer_latched{false};
  std::atomic<bool> writer_shm{false};          // the writer publishes through shared memory too
  std::atomic<std::uint64_t> writer_handle{0};  // its instance handle: its samples come back through iceoryx
  // Delivery: one thread at a time takes and publishes (order); a listener
  // that finds it busy leaves `pending` for the holder to look again.
  std::mutex deliver_mu;
  std::atomic<bool> pending{false};
  std::atomic<bool> handed_over{false};       // the back-pressure thread delivers until the reader is empty
  EndpointQos wq, rq;                         // written under sync_mu_ and peers_mu; stats() reads them under peers_mu
  std::shared_ptr<bus::Topic> local;          // the local topic
  int tap = 0;                                // local -> DDS, on the publishers' threads
  std::shared_ptr<bus::GenericPublisher> in;  // DDS -> local
  std::atomic<std::size_t> remote_readers{0}, remote_writers{0};
  std::atomic<std::uint64_t> sent{0}, unmatched{0}, received{0}, decode_errors{0}, write_errors{0}, incompatible{0};
  std::atomic<std::uint64_t> lost{0}, stalls{0};
  std::atomic<std::size_t> last_size{64};  // serialization buffer guess
  detail::Gid writer_gid{}, reader_gid{};  // ROS 2 graph ids of writer and reader (under sync_mu_)
  std::mutex peers_mu;
  std::map<dds_instance_handle_t, Identity> readers_seen, writers_seen;
};

namespace {

// The entity of a status callback is a writer or a reader of `l`; report who
// joined and who left by comparing the matched set with what we knew.
// `status_count` is the count the status reported: the fallback when the
// entity cannot be queried yet (a match found while it is being created calls
// the listener before dds_create_* returns; sync_topic calls this again).
template <bool kWriter>
void update_peers(Bridge::Link& l, dds_entity_t entity, std::uint32_t status_count, const bus::Logger& log,
                  bool departures_expected, std::mutex& mu, std::condition_variable& cv, std::uint64_t& events) {
  std::vector<dds_instance_handle_t> hs(256);
  const dds_return_t n = kWriter ? dds_get_matched_subscriptions(entity, hs.data(), hs.size())
                                 : dds_get_matched_publications(entity, hs.data(), hs.size());
  if (n < 0) {
    (kWriter ? l.remote_readers : l.remote_writers).store(status_count);
    {
      std::lock_guard lk(mu);
      ++events;
    }
    cv.notify_all();
    return;
  }
  hs.resize(std::min(hs.size(), static_cast<std::size_t>(n)));
  std::vector<std::string> joined, left, mismatched;
  std::size_t now_count = 0;
  {
    std::lock_guard lk(l.peers_mu);
    auto& seen = kWriter ? l.readers_seen : l.writers_seen;
    for (const auto h : hs) {
      if (seen.count(h) != 0) continue;
      dds_builtintopic_endpoint_t* e =
          kWriter ? dds_get_matched_subscription_data(entity, h) : dds_get_matched_publication_data(entity, h);
      Identity who;
      if (e != nullptr) {
        who = detail::read_identity(e->qos);
        dds_builtintopic_free_endpoint(e);
      }
      joined.push_back(who.describe());
      if (!who.type_hash.empty() && l.type != nullptr && who.type_hash != l.type->type_hash) {
        mismatched.push_back(fmt::format("{} carries {} as {}, ours is {}", who.describe(), l.type->name, who.type_hash,
                                         l.type->type_hash));
      }
      seen.emplace(h, who);
    }
    for (auto it = seen.begin(); it != seen.end();) {
      if (std::find(hs.begin(), hs.end(), it->first) == hs.end()) {
        left.push_back(it->second.describe());
        it = seen.erase(it);
      } else {
        ++it;
      }
    }
    now_count = seen.size();
  }
  (kWriter ? l.remote_readers : l.remote_writers).store(now_count);
  const char* what = kWriter ? "subscriber" : "publisher";
  for (const auto& j : joined) log.info("{}: remote {} in {} connected", l.name, what, j);
  for (const auto& m : mismatched) {
    log.warn(
        "{}: the remote {} in {}: the two definitions differ (REP 2011 type hashes), so its messages may not "
        "decode",
        l.name, what, m);
  }
  for (const auto& g : left) {
    if (departures_expected) {
      log.info("{}: the remote {} in {} left; {} remote {}(s) left", l.name, what, g, now_count, what);
    } else {
      log.warn("{}: lost the remote {} in {}; {} remote {}(s) left", l.name, what, g, now_count, what);
    }
  }
  {
    std::lock_guard lk(mu);
    ++events;
  }
  cv.notify_all();
}

}  // namespace

// The listener callbacks need the bridge's match bookkeeping; these statics
// reach it through the link.
struct BridgeAccess {
  static void publication_matched(dds_entity_t w, const dds_publication_matched_status_t st, void* arg) {
    auto* l = static_cast<Bridge::Link*>(arg);
    update_peers<true>(*l, w, st.current_count, l->bridge->logger(), l->bridge->departures_expected_.load(),
                       l->bridge->match_mu_, l->bridge->matched_cv_, l->bridge->match_events_);
  }
  static void subscription_matched(dds_entity_t r, const dds_subscription_matched_status_t st, void* arg) {
    auto* l = static_cast<Bridge::Link*>(arg);
    update_peers<false>(*l, r, st.current_count, l->bridge->logger(), l->bridge->departures_expected_.load(),
                        l->bridge->match_mu_, l->bridge->matched_cv_, l->bridge->match_events_);
  }
  static void refresh_writer(Bridge::Link& l, dds_entity_t w) {
    dds_publication_matched_status_t st{};
    dds_get_publication_matched_status(w, &st);
    publication_matched(w, st, &l);
  }
  static void refresh_reader(Bridge::Link& l, dds_entity_t r) {
    dds_subscription_matched_status_t st{};
    dds_get_subscription_matched_status(r, &st);
    subscription_matched(r, st, &l);
  }
  static void data_available(dds_entity_t r, void* arg) {
    auto* l = static_cast<Bridge::Link*>(arg);
    l->bridge->drain(*l, r, false);
  }
  static void sample_lost(dds_entity_t, const dds_sample_lost_status_t st, void* arg) {
    auto* l = static_cast<Bridge::Link*>(arg);
    if (st.total_count_change <= 0) return;
    const auto n = static_cast<std::uint64_t>(st.total_count_change);
    const auto total = l->lost.fetch_add(n) + n;
    l->local->count_lost(n);  // the live table's dropped column, a recorder's metadata
    l->bridge->logger().error("{}: DDS lost {} message(s) on the way here ({} so far)", l->name, n, total);
  }
  static void remote_publications(dds_entity_t r, void* arg) {
    static_cast<Bridge*>(arg)->read_remote_endpoints(r, true, true);
  }
  static void remote_subscriptions(dds_entity_t r, void* arg) {
    static_cast<Bridge*>(arg)->read_remote_endpoints(r, false, true);
  }
  static void offered_incompatible(dds_entity_t, const dds_offered_incompatible_qos_status_t st, void* arg) {
    auto* l = static_cast<Bridge::Link*>(arg);
    l->incompatible.fetch_add(1);
    l->bridge->logger().warn(
        "{}: a remote subscriber requests QoS the local publishers do not offer ({}); it gets nothing. "
        "Offered here: {}",
        l->name, detail::policy_name(st.last_policy_id), l->wq.describe());
  }
  static void requested_incompatible(dds_entity_t, const dds_requested_incompatible_qos_status_t st, void* arg) {
    auto* l = static_cast<Bridge::Link*>(arg);
    l->incompatible.fetch_add(1);
    l->bridge->logger().warn(
        "{}: a remote publisher offers QoS the local subscribers cannot accept ({}); nothing arrives from it. "
        "Requested here: {} (a best-effort publisher of another program needs best-effort subscribers here, "
        "QoS::sensor_data(); a volatile one cannot serve latched subscribers)",
        l->name, detail::policy_name(st.last_policy_id), l->rq.describe());
  }
};

// ---------------------------------------------------------------------------- Bridge

std::shared_ptr<Bridge> Bridge::create(const std::shared_ptr<bus::Context>& context, BridgeOptions options) {
  bus::NodeOptions no;
  no.name = options.node_name;
  no.context = context;
  auto b = std::make_shared<Bridge>(std::move(no), std::move(options));
  b->attach_graph(b);
  return b;
}

Bridge::Bridge(bus::NodeOptions node_options, BridgeOptions options)
    : Node(std::move(node_options)), options_(std::move(options)) {
  for (const auto& note : options_.settings.notes) logger().warn("{}", note);
  participant_ = std::make_unique<Participant>(options_.settings);
  if (participant_->shared_memory()) {
    logger().info(
        "shared memory on (iceoryx): keep-last, volatile topics reach processes on this machine "
        "without the loopback socket");
  } else if (options_.settings.shared_memory) {
    logger().warn(
        "shared memory was asked for, but no RouDi (iox-roudi) runs on this machine: every topic goes "
        "over loopback");
  }
  origin_ = g_next_origin.fetch_add(1);
  backpressure_ = std::thread([this] { backpressure_loop(); });
  runner_ = std::make_unique<bus::InlineRunner>(
      [this](const void* link, const std::string& node, std::chrono::nanoseconds held) {
        on_inline_stall(*static_cast<Link*>(const_cast<void*>(link)), node, held);
      });
  ros_graph_ =
      std::make_unique<detail::RosGraph>(*participant_, context().log_sink().get(), [this] { return ros_nodes(); });
}

void Bridge::attach_graph(const std::weak_ptr<Bridge>& self) {
  graph_listener_ = context().graph().on_endpoints_changed([weak = self](const std::string& topic) {
    if (auto b = weak.lock()) b->on_graph_change(topic);
  });
}

Bridge::~Bridge() {
  ros_graph_.reset();
  context().graph().remove_on_endpoints_changed(graph_listener_);
  {
    // No publisher may be inside send() once the links go: remove_tap waits.
    std::lock_guard sync(sync_mu_);
    std::lock_guard lk(mu_);
    for (auto& l : links_) {
      if (l->tap != 0) l->local->remove_tap(l->tap);
      l->tap = 0;
    }
  }
  on_stop();
  // Entities go before the links their listeners point to.
  participant_.reset();
}

void Bridge::on_stop() {
  departures_expected_.store(true);
  {
    std::lock_guard lk(mu_);
    if (stopped_) return;
    stopped_ = true;
  }
  {
    std::lock_guard lk(slow_mu_);
    quit_.store(true);
  }
  slow_cv_.notify_all();
  if (backpressure_.joinable()) backpressure_.join();
  runner_->stop();  // what it still held goes to the workers
}

void Bridge::start() {
  {
    std::lock_guard lk(mu_);
    if (started_ || stopped_) return;
    started_ = true;
  }
  watch_remote_endpoints();
  for (const auto& t : context().graph().topics()) sync_topic(t.name);
  ros_graph_->graph_changed();  // nodes without endpoints too
}

void Bridge::watch_remote_endpoints() {
  std::lock_guard sync(sync_mu_);
  auto create = [&](dds_entity_t builtin, dds_on_data_available_fn fn) {
    dds_listener_t* ls = dds_create_listener(this);
    dds_lset_data_available(ls, fn);
    const dds_entity_t r = dds_create_reader(participant_->handle(), builtin, nullptr, ls);
    dds_delete_listener(ls);
    if (r < 0) logger().warn("cannot watch remote endpoints ({}): type mismatches go unnamed", dds_strretcode(r));
    return r < 0 ? 0 : r;
  };
  remote_pubs_.store(create(DDS_BUILTIN_TOPIC_DCPSPUBLICATION, &BridgeAccess::remote_publications));
  remote_subs_.store(create(DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, &BridgeAccess::remote_subscriptions));
}

void Bridge::read_remote_endpoints(dds_entity_t reader, bool writers, bool only_new) {
  // Read, not taken: a node that wants a topic later looks through them again.
  for (;;) {
    void* samples[kEndpointBatch] = {};
    dds_sample_info_t infos[kEndpointBatch];
    const dds_return_t n =
        only_new ? dds_read_mask(reader, samples, infos, kEndpointBatch, kEndpointBatch, DDS_NOT_READ_SAMPLE_STATE)
                 : dds_read(reader, samples, infos, kEndpointBatch, kEndpointBatch);
    if (n <= 0) return;
    for (dds_return_t i = 0; i < n; ++i) {
      if (!infos[i].valid_data || infos[i].instance_state != DDS_IST_ALIVE) continue;
      const auto* e = static_cast<const dds_builtintopic_endpoint_t*>(samples[i]);
      if (e->topic_name == nullptr || e->type_name == nullptr) continue;
      on_remote_endpoint(e->topic_name, e->type_name, detail::read_identity(e->qos).describe(), writers);
    }
    dds_return_loan(reader, samples, n);
    if (n < kEndpointBatch || !only_new) return;
  }
}

void Bridge::on_remote_endpoint(const std::string& dds_topic, const std::string& dds_type, const std::string& who,
                                bool writer) {
  const auto name = ros_topic_name(dds_topic);
  if (!name) return;
  const auto local = context().graph().find(*name);
  if (local) {
    const std::string ours = local->type().dds_type_name();
    if (ours == dds_type) return;
    {
      std::lock_guard lk(remote_mu_);
      const std::string key = *name + "|" + dds_type;
      if (std::find(mismatches_reported_.begin(), mismatches_reported_.end(), key) != mismatches_reported_.end())
        return;
      mismatches_reported_.push_back(key);
    }
    const auto theirs = ros_type_name(dds_type);
    logger().error("{}: a {} in {} uses it as {}, this process as {}: DDS will not connect them, nothing travels",
                   *name, writer ? "publisher" : "subscriber", who, theirs ? *theirs : dds_type, local->type().name);
    return;
  }
  if (!writer || !context().graph().wanted(*name)) return;
  const msg::TypeSupport* type = find_type_by_dds_name(dds_type);
  if (type == nullptr) {
    logger().warn("{}: published in {} as {}, a type this program does not know: not recorded", *name, who, dds_type);
    return;
  }
  {
    std::lock_guard lk(slow_mu_);  // created on the bridge's thread: this may be a DDS listener
    adopt_.emplace_back(*name, type);
  }
  slow_cv_.notify_one();
}

void Bridge::adopt(const std::string& name, const msg::TypeSupport& type) {
  if (context().graph().find(name)) return;
  logger().info("{}: published in another process as {}; a node here wants it", name, type.name);
  bridge_topic(name);
  try {
    context().graph().topic(name, type);  // its wanters subscribe now; their endpoints make the reader
  } catch (const std::invalid_argument& e) {
    logger().error("{}", e.what());
  }
}

void Bridge::bridge_topic(const std::string& topic) {
  {
    std::lock_guard lk(mu_);
    if (!options_.selection.selects(topic)) options_.selection.topics.push_back(topic);
  }
  sync_topic(topic);
}

void Bridge::on_graph_change(const std::string& topic) {
  if (t_in_sync) return;
  if (t_in_listener) {  // the bridge's thread syncs it instead
    {
      std::lock_guard lk(slow_mu_);
      resync_.push_back(topic);
    }
    slow_cv_.notify_one();
    return;
  }
  sync_topic(topic);
}

void Bridge::sync_topic(const std::string& name) {
  std::lock_guard sync(sync_mu_);
  bool selected = false;
  {
    std::lock_guard lk(mu_);
    if (!started_ || stopped_) return;
    selected = options_.selection.selects(name);
  }
  auto topic = context().graph().find(name);
  if (!topic) {
    // A topic a node wants but no one here uses yet: look whether another
    // process publishes it (its type comes from there).
    const dds_entity_t pubs = remote_pubs_.load();
    if (pubs != 0 && context().graph().wanted(name)) read_remote_endpoints(pubs, true, false);
    return;
  }
  if (!selected) return;
  const LocalEndpoints local = local_endpoints(name);
  std::shared_ptr<Link> l = find_link(name);
  if (!l && local.publishers.empty() && local.subscribers.empty()) return;
  t_in_sync = true;
  struct Reset {
    ~Reset() { t_in_sync = false; }
  } reset;
  if (!l) l = add_link(name, topic);
  sync_writer(*l, topic, local.publishers);
  sync_reader(*l, local.subscribers);
  ros_graph_->graph_changed();
}

std::vector<detail::NodeEntities> Bridge::ros_nodes() {
  std::lock_guard sync(sync_mu_);  // the links' entities stay as they are
  std::vector<std::shared_ptr<Link>> links;
  {
    std::lock_guard lk(mu_);
    links = links_;
  }
  auto gid_for = [&](const std::string& topic, bool writer) -> std::optional<detail::Gid> {
    for (const auto& l : links) {
      if (l->name != topic) continue;
      if (writer ? l->writer.load() != 0 : l->reader.load() != 0) return writer ? l->writer_gid : l->reader_gid;
    }
    return std::nullopt;
  };
  std::vector<detail::NodeEntities> out;
  const std::string self = full_name();
  for (const auto& n : context().graph().nodes()) {
    if (n.full_name == self) continue;
    detail::NodeEntities e = detail::split_full_name(n.full_name);
    for (const auto& p : n.publishers)
      if (auto g = gid_for(p.topic, true)) e.writers.push_back(*g);
    for (const auto& s : n.subscriptions)
      if (auto g = gid_for(s.topic, false)) e.readers.push_back(*g);
    out.push_back(std::move(e));
  }
  return out;
}

void Bridge::announce_parameters(const std::vector<std::shared_ptr<bus::Node>>& nodes) {
  std::vector<rcl_interfaces::msg::ParameterEvent> events;
  for (const auto& n : nodes) {
    if (n.get() == this || n->parameters().empty()) continue;
    events.push_back(detail::declared_parameters(n->full_name(), n->parameters()));
  }
  ros_graph_->set_parameter_events(std::move(events));
}

Bridge::LocalEndpoints Bridge::local_endpoints(const std::string& name) {
  LocalEndpoints local;
  const std::string self = full_name();
  for (const auto& n : context().graph().nodes()) {
    if (n.full_name == self) continue;
    for (const auto& e : n.publishers)
      if (e.topic == name) local.publishers.push_back(e.qos);
    for (const auto& e : n.subscriptions)
      if (e.topic == name) local.subscribers.push_back(e.qos);
  }
  return local;
}

std::shared_ptr<Bridge::Link> Bridge::find_link(const std::string& name) const {
  std::lock_guard lk(mu_);
  for (const auto& x : links_)
    if (x->name == name) return x;
  return nullptr;
}

std::shared_ptr<Bridge::Link> Bridge::add_link(const std::string& name, const std::shared_ptr<bus::Topic>& topic) {
  auto l = std::make_shared<Link>();
  l->bridge = this;
  l->name = name;
  l->type = &topic->type();
  l->local = topic;
  l->topic = detail::create_topic(participant_->handle(), dds_topic_name(name), std::string(l->type->dds_type_name()),
                                  l->type, options_.settings.max_sample_bytes);
  std::lock_guard lk(mu_);
  links_.push_back(l);
  return l;
}

void Bridge::sync_writer(Link& L, const std::shared_ptr<bus::Topic>& topic, const std::vector<bus::QoS>& pubs) {
  // A writer exists while the process publishes the topic, with the QoS its
  // publishers need now.
  const EndpointQos wq = offered_qos(pubs);
  if (L.writer.load() != 0 && (pubs.empty() || !same(wq, L.wq))) {
    dds_delete(L.writer.exchange(0));
    L.remote_readers.store(0);
    std::lock_guard lk(L.peers_mu);
    L.readers_seen.clear();
  }
  if (pubs.empty() || L.writer.load() != 0) return;
  {
    std::lock_guard lk(L.peers_mu);
    L.wq = wq;
  }
  detail::Qos q;
  detail::fill_qos(q, wq, false, participant_->identity(), L.type);
  dds_listener_t* ls = dds_create_listener(&L);
  dds_lset_publication_matched(ls, &BridgeAccess::publication_matched);
  dds_lset_offered_incompatible_qos(ls, &BridgeAccess::offered_incompatible);
  const dds_entity_t w = dds_create_writer(participant_->handle(), L.topic.topic, q.q, ls);
  dds_delete_listener(ls);
  if (w < 0) fail("cannot create a DDS writer for " + L.name, w);
  L.writer_latched.store(wq.transient_local);
  L.writer_shm.store(participant_->shared_memory() && dds_is_shared_memory_available(w));
  dds_instance_handle_t ih = 0;
  dds_get_instance_handle(w, &ih);
  L.writer_handle.store(ih);
  if (participant_->shared_memory() && !L.writer_shm.load()) explain_no_shared_memory(L, wq, "publishers");
  L.writer_gid = detail::gid_of(w);
  L.writer.store(w);
  BridgeAccess::refresh_writer(L, w);  // readers matched while it was being created
  if (L.tap != 0) return;
  // Publishers of the topic send on their own thread, once local subscribers
  // have the message; a latched topic replays its history into the
  // (transient-local) writer here.
  Link* raw = &L;
  const std::uint32_t own = origin_;
  L.tap = topic->add_tap([raw, own](const std::shared_ptr<const void>& m, const bus::MessageInfo& info) {
    if (info.origin != own) raw->bridge->send(*raw, m);
  });
}

void Bridge::sync_reader(Link& L, const std::vector<bus::QoS>& subs) {
  // A reader exists while the process subscribes to the topic, with the QoS
  // its subscribers need now.
  EndpointQos rq = requested_qos(subs);
  rq.accept_local = participant_->shared_memory();  // its own writes are dropped in take_available
  if (L.reader.load() != 0 && (subs.empty() || !same(rq, L.rq))) {
    dds_delete(L.reader.exchange(0));  // waits for a listener call in progress
    L.remote_writers.store(0);
    std::lock_guard lk(L.peers_mu);
    L.writers_seen.clear();
  }
  if (subs.empty() || L.reader.load() != 0) return;
  {
    std::lock_guard lk(L.peers_mu);
    L.rq = rq;
  }
  if (!L.in) {
    bus::QoS pq = bus::QoS::keep_last(static_cast<std::size_t>(rq.depth));
    pq.transient_local = rq.transient_local;  // late local subscribers get what came in
    auto in = create_generic_publisher(L.name, *L.type, pq);
    std::lock_guard lk(mu_);
    L.in = std::move(in);
  }
  detail::Qos q;
  detail::fill_qos(q, rq, true, participant_->identity(), L.type);
  dds_listener_t* ls = dds_create_listener(&L);
  dds_lset_subscription_matched(ls, &BridgeAccess::subscription_matched);
  dds_lset_requested_incompatible_qos(ls, &BridgeAccess::requested_incompatible);
  dds_lset_data_available(ls, &BridgeAccess::data_available);
  dds_lset_sample_lost(ls, &BridgeAccess::sample_lost);
  const dds_entity_t r = dds_create_reader(participant_->handle(), L.topic.topic, q.q, ls);
  dds_delete_listener(ls);
  if (r < 0) fail("cannot create a DDS reader for " + L.name, r);
  if (participant_->shared_memory() && !dds_is_shared_memory_available(r)) {
    explain_no_shared_memory(L, rq, "subscribers");
  }
  L.reader_gid = detail::gid_of(r);
  L.reader.store(r);
  BridgeAccess::refresh_reader(L, r);
  drain(L, r, false);  // what arrived before the reader was stored
}

void Bridge::send(Link& l, const std::shared_ptr<const void>& m) {
  const dds_entity_t w = l.writer.load();
  if (w == 0) return;
  // Volatile data nobody remote listens to is not worth serializing; DDS
  // would drop it anyway. Latched data is kept by the writer for late joiners.
  if (!l.writer_latched.load() && l.remote_readers.load() == 0) {
    l.unmatched.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  TL_DDS_PROBE(SendEnter);
  std::vector<std::uint8_t> buf;
  buf.reserve(l.last_size.load(std::memory_order_relaxed));
  try {
    l.type->serialize(m.get(), buf);
  } catch (const std::exception& e) {
    if (worth_logging(l.write_errors.fetch_add(1) + 1)) {
      logger().error("{}: cannot serialize a message for DDS: {}", l.name, e.what());
    }
    return;
  }
  l.last_size.store(buf.size(), std::memory_order_relaxed);
  TL_DDS_PROBE(Serialized);
  std::string why;
  ddsi_serdata* sd = detail::make_serdata_for(w, l.writer_shm.load(), l.topic.sertype, std::move(buf), why);
  if (sd == nullptr) {
    if (worth_logging(l.write_errors.fetch_add(1) + 1)) {
      logger().error("{}: a message was not sent to the processes on this machine: {}", l.name, why);
    }
    return;
  }
  const dds_return_t rc = detail::write_serdata(w, sd);  // takes the reference
  TL_DDS_PROBE(Written);
  if (rc < 0) {
    if (worth_logging(l.write_errors.fetch_add(1) + 1)) {
      logger().error("{}: DDS write failed: {} ({} remote reader(s))", l.name, dds_strretcode(rc),
                     l.remote_readers.load());
    }
    return;
  }
  l.sent.fetch_add(1, std::memory_order_relaxed);
}

void Bridge::drain(Link& l, dds_entity_t reader, bool may_block) {
  l.pending.store(true, std::memory_order_seq_cst);
  while (l.pending.load(std::memory_order_seq_cst) && !quit_.load()) {
    std::unique_lock lk(l.deliver_mu, std::defer_lock);
    if (may_block) {
      lk.lock();
    } else if (!lk.try_lock()) {
      return;  // the holder looks again: it sees `pending`
    }
    l.pending.store(false, std::memory_order_seq_cst);
    if (!may_block && l.handed_over.load()) return;  // the back-pressure thread takes everything
    take_available(l, reader, may_block);
    if (may_block) l.handed_over.store(false);
  }
}

void Bridge::take_available(Link& l, dds_entity_t reader, bool may_block) {
  const bool was_in_listener = t_in_listener;
  t_in_listener = !may_block;
  struct Reset {
    bool value;
    ~Reset() { t_in_listener = value; }
  } reset{was_in_listener};
  // From Cyclone's receive thread, the subscribers' callbacks go to the
  // inline runner when their executor lets them (bus::InlineDelivery): no
  // wake-up of a worker, and no user code on Cyclone's thread. The
  // back-pressure thread leaves them to the workers.
  std::optional<bus::InlineDelivery> inline_delivery;
  if (!may_block) inline_delivery.emplace(*runner_, &l);
  for (;;) {
    if (!may_block && l.in->would_wait()) {
      hand_over(l);
      return;
    }
    ddsi_serdata* sd = nullptr;
    dds_sample_info_t info;
    if (quit_.load() || dds_takecdr(reader, &sd, 1, &info, DDS_ANY_STATE) <= 0) return;
    TL_DDS_PROBE(Taken);
    detail::taking_over(sd);
    if (detail::serdata_lost_before(sd)) count_shared_memory_loss(l);
    // Shared memory delivers our own writes back to us (iceoryx knows no
    // ignore-local): those are the local subscribers' already.
    const bool own = info.publication_handle == l.writer_handle.load() && l.writer_handle.load() != 0;
    if (info.valid_data && !own) {
      std::shared_ptr<void> msg;
      try {
        msg = l.type->deserialize(detail::serdata_bytes(sd));
        TL_DDS_PROBE(Deserialized);
      } catch (const std::exception& e) {
        const auto errors = l.decode_errors.fetch_add(1) + 1;
        if (worth_logging(errors)) {
          Identity who;
          if (auto* ep = dds_get_matched_publication_data(reader, info.publication_handle)) {
            who = detail::read_identity(ep->qos);
            dds_builtintopic_free_endpoint(ep);
          }
          logger().error("{}: dropped a sample from {} that does not decode as {} ({} so far): {}", l.name,
                         who.describe(), l.type->name, errors, e.what());
        }
      }
      if (msg) {
        l.in->publish(std::move(msg), origin_, may_block ? bus::Wait::ForRoom : bus::Wait::Never);
        TL_DDS_PROBE(Delivered);
        if (inline_delivery) inline_delivery->flush();
        l.received.fetch_add(1, std::memory_order_relaxed);
      }
    }
    detail::handing_over(sd);
    ddsi_serdata_unref(sd);
  }
}

void Bridge::explain_no_shared_memory(Link& l, const EndpointQos& q, const char* who) {
  // Cyclone 0.10 carries keep-last, volatile (or shallow transient-local)
  // endpoints through iceoryx; anything else keeps to the socket.
  std::string why;
  if (q.keep_all) {
    why = fmt::format("the {} keep all (QoS::reliable()), shared memory needs keep-last", who);
  } else if (q.transient_local) {
    why = fmt::format("the {} are latched (transient local), shared memory serves volatile topics", who);
  } else {
    why = "Cyclone refused it for this endpoint";
  }
  logger().info("{}: over loopback, not shared memory: {} ({})", l.name, why, q.describe());
}

void Bridge::count_shared_memory_loss(Link& l) {
  // iceoryx says only that chunks were lost since it was last asked: at least one.
  const auto total = l.lost.fetch_add(1) + 1;
  l.local->count_lost(1);
  if (worth_logging(total)) {
    logger().error("{}: shared memory dropped message(s) this process did not take in time ({} time(s) so far)", l.name,
                   total);
  }
}

bool Bridge::is_inline_thread(std::thread::id id) const { return runner_->is_runner_thread(id); }

void Bridge::on_inline_stall(Link& l, const std::string& node, std::chrono::nanoseconds held) {
  // The run keeps the runner's old thread and a fresh one delivers on; if
  // the run slept, its node runs on executor threads from now on (Cyclone's
  // thread never waited for it). Said once per 100.
  if (worth_logging(l.stalls.fetch_add(1) + 1)) {
    logger().warn(
        "{}: the callback of '{}' held the inline delivery thread for {:.0f} ms; a fresh thread delivers the other "
        "subscribers, and a callback that sleeps runs on its executor's threads from now on",
        l.name, node, std::chrono::duration<double, std::milli>(held).count());
  }
}

void Bridge::hand_over(Link& l) {
  if (l.handed_over.exchange(true)) return;
  {
    std::lock_guard lk(slow_mu_);
    slow_links_.push_back(&l);
  }
  slow_cv_.notify_one();
}

void Bridge::backpressure_loop() {
  for (;;) {
    Link* l = nullptr;
    std::vector<std::string> resync;
    std::vector<std::pair<std::string, const msg::TypeSupport*>> adopted;
    {
      std::unique_lock lk(slow_mu_);
      slow_cv_.wait(lk, [&] { return quit_.load() || !slow_links_.empty() || !resync_.empty() || !adopt_.empty(); });
      if (quit_.load()) return;
      resync.swap(resync_);
      adopted.swap(adopt_);
      if (!slow_links_.empty()) {
        l = slow_links_.front();
        slow_links_.erase(slow_links_.begin());
      }
    }
    for (const auto& [topic, type] : adopted) adopt(topic, *type);
    for (const auto& topic : resync) sync_topic(topic);
    if (l == nullptr) continue;
    const dds_entity_t r = l->reader.load();
    if (r != 0) {
      drain(*l, r, true);
    } else {
      l->handed_over.store(false);
    }
  }
}

WaitResult Bridge::wait_for_peers(const std::vector<PeerExpectation>& expected, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  auto check = [&](std::string* missing) {
    std::vector<std::shared_ptr<Link>> links;
    {
      std::lock_guard lk(mu_);
      links = links_;
    }
    bool ok = true;
    for (const auto& e : expected) {
      const Link* l = nullptr;
      for (const auto& x : links)
        if (x->name == e.topic) l = x.get();
      const std::size_t r = l ? l->remote_readers.load() : 0;
      const std::size_t w = l ? l->remote_writers.load() : 0;
      if (r < e.readers || w < e.writers) {
        ok = false;
        if (missing) {
          *missing += fmt::format("{}{}: {} of {} remote subscriber(s), {} of {} remote publisher(s)",
                                  missing->empty() ? "" : "; ", e.topic, r, e.readers, w, e.writers);
        }
      }
    }
    return ok;
  };
  for (;;) {
    std::uint64_t seen;
    {
      std::lock_guard lk(match_mu_);
      seen = match_events_;
    }
    if (check(nullptr)) return {true, {}};
    std::unique_lock lk(match_mu_);
    if (!matched_cv_.wait_until(lk, deadline, [&] { return match_events_ != seen; })) {
      lk.unlock();
      WaitResult r;
      r.ok = check(&r.missing);
      return r;
    }
  }
}

std::vector<LinkStats> Bridge::stats() const {
  std::vector<std::shared_ptr<Link>> links;
  {
    std::lock_guard lk(mu_);
    links = links_;
  }
  std::vector<LinkStats> out;
  for (const auto& l : links) {
    LinkStats s;
    s.topic = l->name;
    s.type = std::string(l->type->name);
    s.writer = l->writer.load() != 0;
    s.reader = l->reader.load() != 0;
    {
      // Not sync_mu_: a callback running inline on the receive thread may ask
      // for stats while sync_topic holds it and waits for that listener.
      std::lock_guard lk(l->peers_mu);
      s.writer_qos = l->wq;
      s.reader_qos = l->rq;
    }
    s.remote_readers = l->remote_readers.load();
    s.remote_writers = l->remote_writers.load();
    s.sent = l->sent.load();
    s.unmatched = l->unmatched.load();
    s.received = l->received.load();
    s.decode_errors = l->decode_errors.load();
    s.write_errors = l->write_errors.load();
    s.incompatible = l->incompatible.load();
    s.lost = l->lost.load();
    s.stalls = l->stalls.load();
    out.push_back(std::move(s));
  }
  std::sort(out.begin(), out.end(), [](const LinkStats& a, const LinkStats& b) { return a.topic < b.topic; });
  return out;
}

}  // namespace tinyline::dds
