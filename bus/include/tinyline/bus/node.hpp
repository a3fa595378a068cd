// SPDX-License-Identifier: Apache-2.0
// A node: a named object in a namespace with parameters, publishers,
// subscriptions and timers. Built from one NodeOptions (so the registry, a
// launch file, or a test can create it the same way), started by on_start()
// when its executor starts (I/O belongs there, not in the constructor, so
// `tinyline describe` can build a node without touching hardware).
#pragma once

#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <type_traits>
#include <vector>

#include <tinyline/bus/context.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/graph.hpp>
#include <tinyline/bus/logging.hpp>
#include <tinyline/bus/names.hpp>
#include <tinyline/bus/params.hpp>
#include <tinyline/bus/qos.hpp>
#include <tinyline/common/status.hpp>
#include <tinyline/msg/type_support.hpp>

namespace tinyline::bus {

struct NodeOptions {
  std::string name;
  std::string ns = "/";
  std::vector<ParamOverride> params;
  std::vector<Remap> remaps;
  std::shared_ptr<Context> context;  ///< required
  std::string type_name;             ///< "pkg/Type" when built by the registry
  SourceLocation where;              ///< the launch-file entry that asked for it

  NodeOptions& param(std::string key, ParamValue v) {
    params.push_back({std::move(key), std::move(v), SourceLocation{"code", 0, 0}});
    return *this;
  }
  NodeOptions& remap(std::string from, std::string to) {
    remaps.push_back({std::move(from), std::move(to)});
    return *this;
  }
};

class Node;

namespace detail {
/// Stamps a message with the clock and a sequence number, hands it to every
/// subscription of the topic, and logs a failure with the publisher's logger.
PublishStatus publish(Topic& topic, Clock& clock, const Logger& logger, std::shared_ptr<const void> msg,
                      std::uint32_t origin, Wait wait = Wait::ForRoom);
}  // namespace detail

/// Typed publisher. publish() hands the same object to every subscriber. It
/// keeps its context alive, so it stays valid after its node is gone.
template <class T>
class Publisher {
 public:
  Publisher(Node& node, std::shared_ptr<Topic> topic, QoS qos);
  ~Publisher();
  Publisher(const Publisher&) = delete;
  Publisher& operator=(const Publisher&) = delete;

  /// Takes ownership; subscribers get shared_ptr<const T> to this object.
  PublishStatus publish(std::unique_ptr<T> msg) { return publish(std::shared_ptr<const T>(std::move(msg))); }
  PublishStatus publish(std::shared_ptr<const T> msg);

  const std::string& topic_name() const { return topic_->name(); }
  std::size_t subscription_count() const { return topic_->subscription_count(); }
  const QoS& qos() const { return qos_; }

 private:
  std::shared_ptr<Context> context_;
  Logger logger_;
  std::shared_ptr<Topic> topic_;
  QoS qos_;
};

/// Untyped publisher for bridges and bag playback: the object must be of the
/// topic's type (as made by its TypeSupport::deserialize).
class GenericPublisher {
 public:
  GenericPublisher(Node& node, std::shared_ptr<Topic> topic, QoS qos);
  ~GenericPublisher();
  GenericPublisher(const GenericPublisher&) = delete;
  GenericPublisher& operator=(const GenericPublisher&) = delete;

  PublishStatus publish(std::shared_ptr<const void> msg, std::uint32_t origin = 0, Wait wait = Wait::ForRoom);
  /// True when publish() would wait now (a reliable subscriber's queue is full).
  bool would_wait() const { return topic_->would_wait(); }
  /// Decodes encapsulated CDR with the topic's type support, then publishes.
  /// Throws cdr::Error on bytes that do not decode.
  PublishStatus publish_serialized(std::span<const std::uint8_t> cdr, std::uint32_t origin = 0);

  const std::string& topic_name() const { return topic_->name(); }
  const msg::TypeSupport& type() const { return topic_->type(); }
  std::size_t subscription_count() const { return topic_->subscription_count(); }

 private:
  std::shared_ptr<Context> context_;
  Logger logger_;
  std::shared_ptr<Topic> topic_;
  QoS qos_;
};

template <class T>
class Subscription : public SubscriptionBase {
 public:
  using Callback = std::function<void(const std::shared_ptr<const T>&, const MessageInfo&)>;
  Subscription(std::string topic, QoS qos, std::shared_ptr<CallbackGroup> group, Callback cb)
      : SubscriptionBase(std::move(topic), &msg::type_support<T>(), qos, std::move(group)), cb_(std::move(cb)) {}

 protected:
  void dispatch(std::shared_ptr<const void>&& m, const MessageInfo& info) override {
    cb_(std::static_pointer_cast<const T>(std::move(m)), info);
  }

 private:
  Callback cb_;
};

class GenericSubscription : public SubscriptionBase {
 public:
  using Callback = std::function<void(const std::shared_ptr<const void>&, const msg::TypeSupport&, const MessageInfo&)>;
  GenericSubscription(std::string topic, const msg::TypeSupport* type, QoS qos, std::shared_ptr<CallbackGroup> group,
                      Callback cb)
      : SubscriptionBase(std::move(topic), type, qos, std::move(group)), cb_(std::move(cb)) {}

 protected:
  void dispatch(std::shared_ptr<const void>&& m, const MessageInfo& info) override { cb_(m, type(), info); }

 private:
  Callback cb_;
};

class Node {
 public:
  explicit Node(NodeOptions options);
  virtual ~Node();
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  /// Called once for every node of an executor before any node's on_start():
  /// read and check what the node needs from files here (calibrations,
  /// scenes) and throw if it is unusable, so a bad input starts nothing
  /// (`tinyline launch --check` calls it too). No side effects others see:
  /// open no device, create no file, start no thread.
  virtual void on_configure() {}
  /// Called once, on the thread that starts the executor, before callbacks run.
  virtual void on_start() {}
  /// Called once when the graph stops, before the node is destroyed.
  virtual void on_stop() {}

  const std::string& name() const { return name_; }
  const std::string& ns() const { return ns_; }
  std::string full_name() const;
  const std::string& type_name() const { return type_name_; }

  Context& context() { return *context_; }
  const std::shared_ptr<Context>& context_ptr() const { return context_; }
  Clock& clock() { return context_->clock(); }
  Time now() const { return context_->clock().now(); }
  const Logger& logger() const { return logger_; }

  /// A core's verdict on the parameters this node read: throws ParamError
  /// "node '/ns/name': <reason>" when it is invalid.
  void require_valid(const common::Status& v) const;

  /// The topic a name given in code resolves to (namespace, ~, remaps).
  std::string resolve_topic(const std::string& name) const;

  template <class T>
  std::shared_ptr<Publisher<T>> create_publisher(const std::string& topic, QoS qos = QoS::keep_last()) {
    auto t = context_->graph().topic(resolve_topic(topic), msg::type_support<T>());
    auto p = std::make_shared<Publisher<T>>(*this, t, qos);
    record_endpoint(true, t->name(), t->type().name, qos);
    return p;
  }

  /// callback: void(std::shared_ptr<const T>), void(const T&), or
  /// void(std::shared_ptr<const T>, const MessageInfo&).
  template <class T, class F>
  std::shared_ptr<Subscription<T>> create_subscription(const std::string& topic, QoS qos, F&& callback) {
    typename Subscription<T>::Callback cb;
    if constexpr (std::is_invocable_v<F&, const std::shared_ptr<const T>&, const MessageInfo&>) {
      cb = std::forward<F>(callback);
    } else if constexpr (std::is_invocable_v<F&, const std::shared_ptr<const T>&>) {
      cb = [f = std::forward<F>(callback)](const std::shared_ptr<const T>& m, const MessageInfo&) mutable { f(m); };
    } else {
      static_assert(std::is_invocable_v<F&, const T&>, "subscription callback has an unsupported signature");
      cb = [f = std::forward<F>(callback)](const std::shared_ptr<const T>& m, const MessageInfo&) mutable { f(*m); };
    }
    auto t = context_->graph().topic(resolve_topic(topic), msg::type_support<T>());
    auto s = std::make_shared<Subscription<T>>(t->name(), qos, group_, std::move(cb));
    attach_subscription(t, s);
    return s;
  }

  std::shared_ptr<GenericPublisher> create_generic_publisher(const std::string& topic, const msg::TypeSupport& type,
                                                             QoS qos = QoS::keep_last());
  std::shared_ptr<GenericSubscription> create_generic_subscription(const std::string& topic,
                                                                   const msg::TypeSupport& type, QoS qos,
                                                                   GenericSubscription::Callback cb);

  /// A periodic callback on the context clock, serial with the node's other callbacks.
  std::shared_ptr<Timer> create_timer(Duration period, std::function<void()> cb);

  /// Declares a parameter and returns its value: the override from the launch
  /// file or command line if one was given, else the default. Throws
  /// ParamError (with the override's file and line) on a wrong type or a
  /// value outside the constraints.
  template <class T>
  T declare_parameter(const std::string& name, const T& default_value, std::string description,
                      ParamConstraints constraints = {}) {
    using Tr = ParamTraits<T>;
    ParamValue v = declare_parameter_value(name, Tr::type, ParamValue(typename Tr::Stored(default_value)),
                                           std::move(description), std::move(constraints));
    if constexpr (std::is_same_v<T, int>) {
      return static_cast<int>(std::get<std::int64_t>(v));
    } else {
      return std::get<typename Tr::Stored>(v);
    }
  }
  /// Declares a float parameter (stored as double).
  float declare_parameter(const std::string& name, float default_value, std::string description,
                          ParamConstraints constraints = {}) {
    return static_cast<float>(
        declare_parameter<double>(name, default_value, std::move(description), std::move(constraints)));
  }

  const std::vector<ParamDescriptor>& parameters() const { return params_; }
  /// Throws ParamError naming the first override that matches no declared
  /// parameter (with the list of known ones).
  void check_unused_overrides() const;

  NodeInfo describe() const;
  const std::shared_ptr<CallbackGroup>& callback_group() const { return group_; }

  // Used by Executor.
  std::vector<std::shared_ptr<Timer>> timers() const;

 private:
  ParamValue declare_parameter_value(const std::string& name, ParamType type, ParamValue default_value,
                                     std::string description, ParamConstraints constraints);
  void attach_subscription(const std::shared_ptr<Topic>& t, const std::shared_ptr<SubscriptionBase>& s);
  /// Throws ParamError if `d` names an input file that cannot be read (ParamConstraints::File::Input).
  void check_input_file(const ParamDescriptor& d, const std::string& who) const;
  void record_endpoint(bool publisher, const std::string& topic, std::string_view type, const QoS& qos);

  std::shared_ptr<Context> context_;
  std::string name_;
  std::string ns_;
  std::string type_name_;
  std::vector<Remap> remaps_;
  std::vector<ParamOverride> overrides_;
  SourceLocation where_;
  Logger logger_;
  std::shared_ptr<CallbackGroup> group_;
  std::vector<ParamDescriptor> params_;
  mutable std::mutex mu_;
  std::vector<std::pair<std::shared_ptr<Topic>, std::shared_ptr<SubscriptionBase>>> subs_;
  std::vector<std::shared_ptr<Timer>> timers_;
  std::vector<EndpointInfo> pub_info_;
  std::vector<EndpointInfo> sub_info_;
};

// ---------------------------------------------------------------------------- Publisher<T>

template <class T>
Publisher<T>::Publisher(Node& node, std::shared_ptr<Topic> topic, QoS qos)
    : context_(node.context_ptr()), logger_(node.logger()), topic_(std::move(topic)), qos_(qos) {
  topic_->add_publisher(qos_);
}

template <class T>
Publisher<T>::~Publisher() {
  topic_->remove_publisher();
}

template <class T>
PublishStatus Publisher<T>::publish(std::shared_ptr<const T> msg) {
  return detail::publish(*topic_, context_->clock(), logger_, std::static_pointer_cast<const void>(std::move(msg)), 0);
}

}  // namespace tinyline::bus
