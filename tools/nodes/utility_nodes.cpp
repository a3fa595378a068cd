// SPDX-License-Identifier: Apache-2.0
#include <tinyline/tools/nodes.hpp>

#include <tinyline/msg/std_msgs/string.hpp>
#include <tinyline/msg/yaml_writer.hpp>

namespace tinyline::tools {

namespace {

const msg::TypeSupport& type_param(bus::Node& n, const std::string& value) {
  const msg::TypeSupport* ts = msg::find_type_support(value);
  if (ts == nullptr) {
    std::string known;
    for (const auto* t : msg::all_type_supports()) known += (known.empty() ? "" : ", ") + std::string(t->name);
    throw std::invalid_argument("node '" + n.full_name() + "': unknown message type '" + value + "' (known: " + known +
                                ")");
  }
  return *ts;
}

class Echo : public bus::Node {
 public:
  explicit Echo(bus::NodeOptions o) : Node(std::move(o)) {
    const auto type = declare_parameter<std::string>("type", "std_msgs/msg/String", "message type of the topic");
    const int max_array = declare_parameter("max_array", 16, "elements of long arrays to show (0: all)",
                                            bus::ParamConstraints::at_least(0));
    const int depth = declare_parameter("depth", 10, "queue depth", bus::ParamConstraints::at_least(1));
    sub_ = create_generic_subscription(
        "input", type_param(*this, type), bus::QoS::keep_last(static_cast<std::size_t>(depth)),
        [this, max_array](const std::shared_ptr<const void>& m, const msg::TypeSupport& ts, const bus::MessageInfo&) {
          msg::YamlWriter y(static_cast<std::size_t>(max_array));
          ts.to_yaml(m.get(), y);
          logger().info("{}:\n{}---", sub_->topic_name(), y.str());
        });
  }

 private:
  std::shared_ptr<bus::GenericSubscription> sub_;
};

class Relay : public bus::Node {
 public:
  explicit Relay(bus::NodeOptions o) : Node(std::move(o)) {
    const auto& ts =
        type_param(*this, declare_parameter<std::string>("type", "std_msgs/msg/String", "message type of the topic"));
    const int depth = declare_parameter("depth", 10, "queue depth", bus::ParamConstraints::at_least(1));
    pub_ = create_generic_publisher("output", ts, bus::QoS::keep_last(static_cast<std::size_t>(depth)));
    sub_ = create_generic_subscription(
        "input", ts, bus::QoS::keep_last(static_cast<std::size_t>(depth)),
        [this](const std::shared_ptr<const void>& m, const msg::TypeSupport&, const bus::MessageInfo&) {
          pub_->publish(m);  // the same object: no copy
        });
  }

 private:
  std::shared_ptr<bus::GenericPublisher> pub_;
  std::shared_ptr<bus::GenericSubscription> sub_;
};

class Pulse : public bus::Node {
 public:
  explicit Pulse(bus::NodeOptions o) : Node(std::move(o)) {
    const double rate =
        declare_parameter("rate_hz", 10.0, "publish rate [Hz]", bus::ParamConstraints::range(0.001, 100000.0));
    text_ = declare_parameter<std::string>("text", "pulse", "text before the counter");
    limit_ = declare_parameter("count", 0, "messages to publish, then stay quiet (0: no limit)",
                               bus::ParamConstraints::at_least(0));
    pub_ = create_publisher<std_msgs::msg::String>("output");
    timer_ = create_timer(bus::from_seconds(1.0 / rate), [this] {
      if (limit_ > 0 && count_ >= static_cast<std::uint64_t>(limit_)) {
        timer_->cancel();
        return;
      }
      auto m = std::make_unique<std_msgs::msg::String>();
      m->data = text_ + " " + std::to_string(++count_);
      pub_->publish(std::move(m));
    });
  }

 private:
  std::string text_;
  int limit_ = 0;
  std::uint64_t count_ = 0;
  std::shared_ptr<bus::Publisher<std_msgs::msg::String>> pub_;
  std::shared_ptr<bus::Timer> timer_;
};

}  // namespace

void register_nodes(bus::NodeRegistry& r) {
  r.add<Echo>("tinyline", "echo", "logs every message of a topic as YAML (remap 'input')");
  r.add<Relay>("tinyline", "relay", "republishes 'input' as 'output' without copying");
  r.add<Pulse>("tinyline", "pulse", "publishes a numbered text on 'output' at a fixed rate");
  register_static_transform(r);
  register_cloud_stream(r);
}

}  // namespace tinyline::tools
