// SPDX-License-Identifier: Apache-2.0
#include "ros_graph.hpp"

#include <algorithm>
#include <cstring>
#include <type_traits>
#include <utility>
#include <variant>

#include <tinyline/bus/log_observer.hpp>
#include <tinyline/msg/rmw_dds_common/participant_entities_info.hpp>

#include "entities.hpp"
#include "serdata.hpp"

namespace tinyline::dds::detail {

namespace {

constexpr std::size_t kRosoutDepth = 1000;  // rcl's rosout publisher
constexpr std::chrono::seconds kRosoutLifespan{10};

EndpointQos make_qos(bool transient_local, int depth) {
  EndpointQos q;
  q.reliable = true;
  q.transient_local = transient_local;
  q.depth = depth;
  q.max_blocking = std::chrono::nanoseconds(0);  // never hold up the graph's thread
  return q;
}

std::uint8_t ros_level(bus::LogLevel l) {
  switch (l) {
    case bus::LogLevel::Debug: return rcl_interfaces::msg::Log::DEBUG;
    case bus::LogLevel::Info: return rcl_interfaces::msg::Log::INFO;
    case bus::LogLevel::Warn: return rcl_interfaces::msg::Log::WARN;
    case bus::LogLevel::Error: return rcl_interfaces::msg::Log::ERROR;
  }
  return rcl_interfaces::msg::Log::INFO;
}

builtin_interfaces::msg::Time wall_now() {
  const auto ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  builtin_interfaces::msg::Time t;
  t.sec = static_cast<std::int32_t>(ns / 1'000'000'000);
  t.nanosec = static_cast<std::uint32_t>(ns % 1'000'000'000);
  return t;
}

rmw_dds_common::msg::Gid to_msg(const Gid& g) {
  rmw_dds_common::msg::Gid m;
  std::copy(g.begin(), g.end(), m.data.begin());
  return m;
}

void on_parameter_reader(dds_entity_t, const dds_publication_matched_status_t st, void* arg) {
  if (st.current_count > 0) static_cast<RosGraph*>(arg)->reader_matched();
}

/// rcl_interfaces/msg/ParameterType's constants.
enum ParameterType : std::uint8_t {
  kBool = 1,
  kInteger = 2,
  kDouble = 3,
  kString = 4,
  kBoolArray = 6,
  kIntegerArray = 7,
  kDoubleArray = 8,
  kStringArray = 9
};

rcl_interfaces::msg::ParameterValue to_msg(const bus::ParamValue& v) {
  rcl_interfaces::msg::ParameterValue m;
  std::visit(
      [&m](const auto& x) {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, bool>) {
          m.type = kBool, m.bool_value = x;
        } else if constexpr (std::is_same_v<T, std::int64_t>) {
          m.type = kInteger, m.integer_value = x;
        } else if constexpr (std::is_same_v<T, double>) {
          m.type = kDouble, m.double_value = x;
        } else if constexpr (std::is_same_v<T, std::string>) {
          m.type = kString, m.string_value = x;
        } else if constexpr (std::is_same_v<T, std::vector<bool>>) {
          m.type = kBoolArray, m.bool_array_value.assign(x.begin(), x.end());
        } else if constexpr (std::is_same_v<T, std::vector<std::int64_t>>) {
          m.type = kIntegerArray, m.integer_array_value = x;
        } else if constexpr (std::is_same_v<T, std::vector<double>>) {
          m.type = kDoubleArray, m.double_array_value = x;
        } else {
          m.type = kStringArray, m.string_array_value = x;
        }
      },
      v);
  return m;
}

}  // namespace

rcl_interfaces::msg::ParameterEvent declared_parameters(const std::string& node,
                                                        const std::vector<bus::ParamDescriptor>& params) {
  rcl_interfaces::msg::ParameterEvent e;
  e.stamp = wall_now();
  e.node = node;
  for (const auto& d : params) {
    rcl_interfaces::msg::Parameter p;
    p.name = d.name;
    p.value = to_msg(d.value);
    e.new_parameters.push_back(std::move(p));
  }
  return e;
}

Gid gid_of(dds_entity_t entity) {
  dds_guid_t g{};
  Gid out{};
  if (dds_get_guid(entity, &g) == DDS_RETCODE_OK) std::memcpy(out.data(), g.v, out.size());
  return out;
}

NodeEntities split_full_name(const std::string& full_name) {
  NodeEntities n;
  const auto slash = full_name.rfind('/');
  n.ns = slash == 0 || slash == std::string::npos ? "/" : full_name.substr(0, slash);
  n.name = slash == std::string::npos ? full_name : full_name.substr(slash + 1);
  return n;
}

std::string ros_logger_name(const std::string& full_name) {
  std::string s = full_name.rfind('/', 0) == 0 ? full_name.substr(1) : full_name;
  std::replace(s.begin(), s.end(), '/', '.');
  return s;
}

TypedWriter::TypedWriter(Participant& p, const std::string& dds_topic, const msg::TypeSupport& type,
                         const EndpointQos& qos, std::chrono::nanoseconds lifespan, dds_listener_t* listener)
    : type_(&type),
      topic_(create_topic(p.handle(), dds_topic, type.dds_type_name(), &type, p.settings().max_sample_bytes)) {
  Qos q;
  fill_qos(q, qos, false, p.identity(), &type);
  if (lifespan.count() > 0) dds_qset_lifespan(q.q, lifespan.count());
  writer_ = dds_create_writer(p.handle(), topic_.topic, q.q, listener);
  if (writer_ < 0) {
    const auto rc = writer_;
    dds_delete(topic_.topic);
    fail("cannot create a DDS writer on '" + dds_topic + "'", rc);
  }
}

TypedWriter::~TypedWriter() {
  dds_delete(writer_);
  dds_delete(topic_.topic);
}

bool TypedWriter::write(const void* m) {
  std::vector<std::uint8_t> buf;
  type_->serialize(m, buf);
  ddsi_serdata* sd = make_serdata(topic_.sertype, std::move(buf));
  sd->timestamp.v = dds_time();  // the source time: lifespan counts from it, and writecdr takes it as given
  return write_serdata(writer_, sd) >= 0;
}

namespace {

dds_listener_t* parameter_listener(RosGraph* g) {
  dds_listener_t* ls = dds_create_listener(g);
  dds_lset_publication_matched(ls, &on_parameter_reader);
  return ls;
}

/// Owns a listener for the duration of one writer's creation.
struct ListenerHolder {
  dds_listener_t* ls;
  ~ListenerHolder() { dds_delete_listener(ls); }
};

}  // namespace

RosGraph::RosGraph(Participant& p, const bus::LogSink* sink, std::function<std::vector<NodeEntities>()> nodes)
    : nodes_(std::move(nodes)),
      participant_gid_(gid_of(p.handle())),
      discovery_(p, "ros_discovery_info", msg::type_support<rmw_dds_common::msg::ParticipantEntitiesInfo>(),
                 make_qos(true, 1), {}, nullptr),
      rosout_(p, "rt/rosout", msg::type_support<rcl_interfaces::msg::Log>(),
              make_qos(true, static_cast<int>(kRosoutDepth)), kRosoutLifespan, nullptr),
      parameter_events_(p, "rt/parameter_events", msg::type_support<rcl_interfaces::msg::ParameterEvent>(),
                        make_qos(false, 1000), {}, ListenerHolder{parameter_listener(this)}.ls) {
  if (sink != nullptr) observer_ = bus::add_log_observer(sink, [this](const bus::LogRecord& r) { on_log(r); });
  thread_ = std::thread([this] { run(); });
}

RosGraph::~RosGraph() {
  if (observer_ != 0) bus::remove_log_observer(observer_);
  {
    std::lock_guard lk(mu_);
    quit_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void RosGraph::graph_changed() {
  {
    std::lock_guard lk(mu_);
    dirty_ = true;
  }
  cv_.notify_all();
}

void RosGraph::set_parameter_events(std::vector<rcl_interfaces::msg::ParameterEvent> events) {
  {
    std::lock_guard lk(mu_);
    params_ = std::move(events);
  }
  cv_.notify_all();
}

void RosGraph::reader_matched() {
  {
    std::lock_guard lk(mu_);
    param_reader_ = true;
  }
  cv_.notify_all();
}

std::uint64_t RosGraph::dropped_logs() const {
  std::lock_guard lk(mu_);
  return dropped_logs_;
}

void RosGraph::on_log(const bus::LogRecord& r) {
  rcl_interfaces::msg::Log m;
  m.stamp = wall_now();  // rcl stamps /rosout with the system clock
  m.level = ros_level(r.level);
  m.name = ros_logger_name(r.logger);
  m.msg = r.text;
  {
    std::lock_guard lk(mu_);
    if (logs_.size() >= kRosoutDepth) {  // a burst: keep the newest, as the topic's depth would
      logs_.pop_front();
      ++dropped_logs_;
    }
    logs_.push_back(std::move(m));
  }
  cv_.notify_all();
}

void RosGraph::run() {
  std::unique_lock lk(mu_);
  for (;;) {
    cv_.wait(lk, [&] { return quit_ || dirty_ || !logs_.empty() || (param_reader_ && !params_.empty()); });
    if (quit_) return;
    const bool announce_now = std::exchange(dirty_, false);
    std::deque<rcl_interfaces::msg::Log> logs;
    logs.swap(logs_);
    std::vector<rcl_interfaces::msg::ParameterEvent> params;
    if (param_reader_) params.swap(params_);
    lk.unlock();
    if (announce_now) announce();
    for (const auto& m : logs) rosout_.write(&m);
    for (const auto& m : params) parameter_events_.write(&m);
    lk.lock();
  }
}

void RosGraph::announce() {
  rmw_dds_common::msg::ParticipantEntitiesInfo info;
  info.gid = to_msg(participant_gid_);
  // Every node writes /rosout and /parameter_events, as a ROS 2 node does.
  const Gid rosout = rosout_.gid(), params = parameter_events_.gid();
  for (auto& n : nodes_()) {
    rmw_dds_common::msg::NodeEntitiesInfo e;
    e.node_namespace = n.ns;
    e.node_name = n.name;
    for (const auto& g : n.readers) e.reader_gid_seq.push_back(to_msg(g));
    for (const auto& g : n.writers) e.writer_gid_seq.push_back(to_msg(g));
    e.writer_gid_seq.push_back(to_msg(rosout));
    e.writer_gid_seq.push_back(to_msg(params));
    info.node_entities_info_seq.push_back(std::move(e));
  }
  discovery_.write(&info);
}

}  // namespace tinyline::dds::detail
