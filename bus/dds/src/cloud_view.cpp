// SPDX-License-Identifier: Apache-2.0
#include <tinyline/dds/cloud_view.hpp>

#include <dds/ddsc/dds_loan_api.h>
#include <dds/dds.h>

#include <atomic>
#include <mutex>

#include <tinyline/dds/naming.hpp>
#include <tinyline/msg/sensor_msgs/point_cloud2.hpp>

#include "entities.hpp"
#include "serdata.hpp"

namespace tinyline::dds {

struct CloudViewSubscription::State : std::enable_shared_from_this<State> {
  detail::TopicHandle topic;
  dds_entity_t reader = 0;
  Callback callback;
  std::atomic<std::uint64_t> received{0}, decode_errors{0};
  // The last view (or the subscription) gone: the reader, and with it the
  // iceoryx subscriber the chunks go back to, may go.
  ~State() {
    if (reader > 0) dds_delete(reader);
    if (topic.topic > 0) dds_delete(topic.topic);
  }
};

namespace {

using State = CloudViewSubscription::State;

// PointCloud2's fields in their CDR order (the generated cdr_read's), the
// data left where it lies.
std::shared_ptr<PointCloud2View> parse(std::span<const std::uint8_t> bytes) {
  auto v = std::make_shared<PointCloud2View>();
  cdr::Reader r = msg::open_encapsulated(bytes);
  r.at("header");
  cdr_read(r, v->header);
  r.at("height");
  v->height = r.get<std::uint32_t>();
  r.at("width");
  v->width = r.get<std::uint32_t>();
  r.at("fields");
  v->fields.resize(r.get_count(13, 0));
  for (auto& f : v->fields) cdr_read(r, f);
  r.at("is_bigendian");
  v->is_bigendian = r.get<bool>();
  r.at("point_step");
  v->point_step = r.get<std::uint32_t>();
  r.at("row_step");
  v->row_step = r.get<std::uint32_t>();
  r.at("data");
  v->data = r.get_bytes(r.get_count(1, 0));
  r.at("is_dense");
  v->is_dense = r.get<bool>();
  return v;
}

// Hands one taken sample to the callback as a view holding it.
void hand_over(State& st, ddsi_serdata* sd) {
  // The view's holder keeps the state (and so the reader) alive.
  std::shared_ptr<const void> hold(sd, [keep = st.shared_from_this()](const void* p) {
    auto* d = const_cast<ddsi_serdata*>(static_cast<const ddsi_serdata*>(p));
    detail::handing_over(d);
    ddsi_serdata_unref(d);
  });
  std::shared_ptr<PointCloud2View> v;
  try {
    v = parse(detail::serdata_bytes(sd));
  } catch (const std::exception&) {
    st.decode_errors.fetch_add(1);
    return;
  }
  v->in_shared_memory = sd->iox_chunk != nullptr;
  v->sample = std::move(hold);
  st.received.fetch_add(1);
  st.callback(std::move(v));
}

void on_data(dds_entity_t reader, void* arg) {
  auto& st = *static_cast<State*>(arg);
  for (;;) {
    ddsi_serdata* sd = nullptr;
    dds_sample_info_t info;
    if (dds_takecdr(reader, &sd, 1, &info, DDS_ANY_STATE) <= 0) return;
    detail::taking_over(sd);
    if (info.valid_data) {
      hand_over(st, sd);
    } else {
      ddsi_serdata_unref(sd);
    }
  }
}

}  // namespace

CloudViewSubscription::CloudViewSubscription(Participant& participant, const std::string& topic, int depth,
                                             Callback callback)
    : state_(std::make_shared<State>()) {
  const auto& type = msg::type_support<sensor_msgs::msg::PointCloud2>();
  state_->callback = std::move(callback);
  state_->topic = detail::create_topic(participant.handle(), dds_topic_name(topic), type.dds_type_name(), &type,
                                       participant.settings().max_sample_bytes);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, depth);
  dds_listener_t* ls = dds_create_listener(state_.get());
  dds_lset_data_available(ls, &on_data);
  state_->reader = dds_create_reader(participant.handle(), state_->topic.topic, q, ls);
  dds_delete_listener(ls);
  dds_delete_qos(q);
  if (state_->reader < 0) detail::fail("cannot create a DDS reader for " + topic, state_->reader);
}

CloudViewSubscription::~CloudViewSubscription() {
  // Waits for a callback in progress; views handed out keep the reader.
  dds_set_listener(state_->reader, nullptr);
}

bool CloudViewSubscription::shared_memory() const { return dds_is_shared_memory_available(state_->reader); }
std::uint64_t CloudViewSubscription::received() const { return state_->received.load(); }
std::uint64_t CloudViewSubscription::decode_errors() const { return state_->decode_errors.load(); }

}  // namespace tinyline::dds
