// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/node.hpp>

#include <algorithm>

#include <fmt/format.h>

#include <tinyline/bus/files.hpp>

namespace tinyline::bus {

Node::Node(NodeOptions options)
    : context_(std::move(options.context)),
      name_(std::move(options.name)),
      ns_(normalize_namespace(options.ns)),
      type_name_(std::move(options.type_name)),
      remaps_(std::move(options.remaps)),
      overrides_(std::move(options.params)),
      where_(std::move(options.where)) {
  if (!context_) throw std::invalid_argument("NodeOptions.context is required");
  if (name_.empty() || name_.find('/') != std::string::npos || name_[0] == '~') {
    throw std::invalid_argument("node name '" + name_ + "' is invalid: one token, no '/'");
  }
  validate_name(name_, "node name");
  if (ns_ != "/") validate_name(ns_, "namespace");
  logger_ = context_->logger(full_name());
  group_ = std::make_shared<CallbackGroup>(full_name());
  group_->on_error = [this](const std::string& what) { logger_.error("callback failed: {}", what); };
  context_->graph().add_node(this, [this] { return describe(); });
}

Node::~Node() {
  group_->shutdown();
  context_->graph().remove_node(this);
  std::vector<std::string> touched;
  {
    std::lock_guard lk(mu_);
    for (auto& [topic, sub] : subs_) {
      topic->remove_subscription(sub.get());
      sub->cancel();
    }
    for (auto& t : timers_) t->cancel();
    for (const auto* list : {&pub_info_, &sub_info_}) {
      for (const auto& e : *list) {
        if (std::find(touched.begin(), touched.end(), e.topic) == touched.end()) touched.push_back(e.topic);
      }
    }
  }
  for (const auto& t : touched) context_->graph().endpoints_changed(t);
}

std::string Node::full_name() const { return (ns_ == "/" ? "" : ns_) + "/" + name_; }

void Node::require_valid(const common::Status& v) const {
  if (!v.ok()) throw ParamError({}, "node '" + full_name() + "': " + v.message);
}

std::string Node::resolve_topic(const std::string& name) const {
  return apply_remaps(resolve_name(name, ns_, name_), remaps_, ns_, name_);
}

void Node::attach_subscription(const std::shared_ptr<Topic>& t, const std::shared_ptr<SubscriptionBase>& s) {
  {
    std::lock_guard lk(mu_);
    subs_.emplace_back(t, s);
    sub_info_.push_back(EndpointInfo{t->name(), std::string(t->type().name), s->qos()});
  }
  group_->add_subscription(s);  // before the topic: its queue is polled from its first message
  t->add_subscription(s);
  context_->graph().endpoints_changed(t->name());
}

void Node::record_endpoint(bool publisher, const std::string& topic, std::string_view type, const QoS& qos) {
  // A reliable publisher may wait for room: this node's callbacks must not
  // run on a transport's delivery thread (InlineDelivery).
  if (publisher && qos.history == QoS::History::Reliable) group_->refuse_inline();
  {
    std::lock_guard lk(mu_);
    (publisher ? pub_info_ : sub_info_).push_back(EndpointInfo{topic, std::string(type), qos});
  }
  context_->graph().endpoints_changed(topic);
}

std::shared_ptr<GenericPublisher> Node::create_generic_publisher(const std::string& topic, const msg::TypeSupport& type,
                                                                 QoS qos) {
  auto t = context_->graph().topic(resolve_topic(topic), type);
  auto p = std::make_shared<GenericPublisher>(*this, t, qos);
  record_endpoint(true, t->name(), type.name, qos);
  return p;
}

std::shared_ptr<GenericSubscription> Node::create_generic_subscription(const std::string& topic,
                                                                       const msg::TypeSupport& type, QoS qos,
                                                                       GenericSubscription::Callback cb) {
  auto t = context_->graph().topic(resolve_topic(topic), type);
  auto s = std::make_shared<GenericSubscription>(t->name(), &t->type(), qos, group_, std::move(cb));
  attach_subscription(t, s);
  return s;
}

std::shared_ptr<Timer> Node::create_timer(Duration period, std::function<void()> cb) {
  auto t = std::make_shared<Timer>(period, std::move(cb));
  {
    std::lock_guard lk(mu_);
    timers_.push_back(t);
  }
  if (Executor* ex = group_->executor()) ex->add_timer(t, group_);
  return t;
}

std::vector<std::shared_ptr<Timer>> Node::timers() const {
  std::lock_guard lk(mu_);
  return timers_;
}

PublishStatus detail::publish(Topic& topic, Clock& clock, const Logger& logger, std::shared_ptr<const void> msg,
                              std::uint32_t origin, Wait wait) {
  if (!msg) throw std::invalid_argument("publish on " + topic.name() + ": null message");
  MessageInfo info;
  info.publish_time = clock.now();
  info.sequence = topic.next_sequence();
  info.origin = origin;
  std::string why;
  const PublishStatus st = topic.publish(std::move(msg), info, &why, wait);
  if (!st.ok()) logger.error("publish on {} failed for {} subscriber(s): {}", topic.name(), st.failed, why);
  return st;
}

ParamValue Node::declare_parameter_value(const std::string& name, ParamType type, ParamValue default_value,
                                         std::string description, ParamConstraints constraints) {
  for (const auto& p : params_) {
    if (p.name == name) throw std::logic_error("node '" + full_name() + "' declares parameter '" + name + "' twice");
  }
  ParamDescriptor d;
  d.name = name;
  d.type = type;
  d.default_value = default_value;
  d.value = default_value;
  d.description = std::move(description);
  d.constraints = std::move(constraints);
  const std::string who = fmt::format("node '{}'{}", full_name(), type_name_.empty() ? "" : " (" + type_name_ + ")");
  const ParamOverride* chosen = nullptr;
  for (const auto& o : overrides_) {
    if (o.name == name) chosen = &o;  // the last one wins, as in ROS 2
  }
  if (chosen != nullptr) {
    auto v = coerce(chosen->value, type);
    if (!v) {
      throw ParamError(chosen->where,
                       fmt::format("{}: parameter '{}' expects {}, got {} {}", who, name, to_string(type),
                                   to_string(type_of(chosen->value)), format_value(chosen->value)));
    }
    d.value = *v;
    d.set_from = chosen->where;
  } else if (d.constraints.required) {
    throw ParamError(where_, fmt::format("{}: parameter '{}' is required ({})", who, name, d.description));
  }
  if (auto why = violates(d.value, d.constraints)) {
    throw ParamError(chosen ? chosen->where : where_,
                     fmt::format("{}: parameter '{}' out of range: {}", who, name, *why));
  }
  check_input_file(d, who);
  params_.push_back(d);
  return d.value;
}

void Node::check_input_file(const ParamDescriptor& d, const std::string& who) const {
  const auto* path = std::get_if<std::string>(&d.value);
  if (d.constraints.file != ParamConstraints::File::Input || path == nullptr || !d.constraints.names_file(*path)) {
    return;
  }
  try {
    files::check_input(*path, "file", d.constraints.file_max_bytes);
  } catch (const files::FileError& e) {
    throw ParamError(d.set_from.known() ? d.set_from : where_,
                     fmt::format("{}: parameter '{}': {}", who, d.name, e.what()));
  }
}

void Node::check_unused_overrides() const {
  for (const auto& o : overrides_) {
    bool found = false;
    for (const auto& p : params_) found = found || p.name == o.name;
    if (!found) {
      std::string known;
      for (const auto& p : params_) known += (known.empty() ? "" : ", ") + p.name;
      throw ParamError(o.where, fmt::format("node '{}'{}: unknown parameter '{}' (known: {})", full_name(),
                                            type_name_.empty() ? "" : " (" + type_name_ + ")", o.name,
                                            known.empty() ? "none" : known));
    }
  }
}

NodeInfo Node::describe() const {
  std::lock_guard lk(mu_);
  return NodeInfo{full_name(), type_name_, pub_info_, sub_info_};
}

// ---------------------------------------------------------------------------- GenericPublisher

GenericPublisher::GenericPublisher(Node& node, std::shared_ptr<Topic> topic, QoS qos)
    : context_(node.context_ptr()), logger_(node.logger()), topic_(std::move(topic)), qos_(qos) {
  topic_->add_publisher(qos_);
}

GenericPublisher::~GenericPublisher() { topic_->remove_publisher(); }

PublishStatus GenericPublisher::publish(std::shared_ptr<const void> msg, std::uint32_t origin, Wait wait) {
  return detail::publish(*topic_, context_->clock(), logger_, std::move(msg), origin, wait);
}

PublishStatus GenericPublisher::publish_serialized(std::span<const std::uint8_t> cdr, std::uint32_t origin) {
  return publish(topic_->type().deserialize(cdr), origin);
}

}  // namespace tinyline::bus
