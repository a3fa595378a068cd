// SPDX-License-Identifier: Apache-2.0
// bus::testing::NodeRig, the node-test helper every package's node tests use:
// registration, creation by type, collection of a topic, stepped time, the log.
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include <tinyline/bus/testing.hpp>
#include <tinyline/msg/std_msgs/string.hpp>

namespace bus = tinyline::bus;
using StringMsg = tinyline::std_msgs::msg::String;
using namespace std::chrono_literals;

namespace {

// Echoes "in" to "out" with a prefix parameter, and says "tick N" on "ticks"
// every 100 ms of (sim) time.
class EchoNode : public bus::Node {
 public:
  explicit EchoNode(bus::NodeOptions o) : Node(std::move(o)) {
    prefix_ = declare_parameter<std::string>("prefix", ">", "put before each echoed text");
    out_ = create_publisher<StringMsg>("out");
    ticks_ = create_publisher<StringMsg>("ticks");
    in_ = create_subscription<StringMsg>("in", bus::QoS::keep_last(10), [this](const StringMsg& m) {
      if (m.data.empty()) {
        logger().warn("empty text on 'in'");
        return;
      }
      auto e = std::make_unique<StringMsg>();
      e->data = prefix_ + m.data;
      out_->publish(std::move(e));
    });
    timer_ = create_timer(100ms, [this] {
      auto t = std::make_unique<StringMsg>();
      t->data = "tick " + std::to_string(++n_);
      ticks_->publish(std::move(t));
    });
  }

 private:
  std::string prefix_;
  int n_ = 0;
  std::shared_ptr<bus::Publisher<StringMsg>> out_, ticks_;
  std::shared_ptr<bus::Subscription<StringMsg>> in_;
  std::shared_ptr<bus::Timer> timer_;
};

void register_echo(bus::NodeRegistry& r) { r.add<EchoNode>("demo", "echo", "echoes text"); }

std::unique_ptr<StringMsg> text(std::string s) {
  auto m = std::make_unique<StringMsg>();
  m->data = std::move(s);
  return m;
}

}  // namespace

TEST(NodeRig, RunsARegisteredNodeOnSteppedTimeAndCollectsItsOutput) {
  bus::testing::NodeRig rig({&register_echo}, bus::Time::from_seconds(10.0));
  auto& out = rig.collect<StringMsg>("out");
  auto& ticks = rig.collect<StringMsg>("ticks");
  bus::NodeOptions o;
  o.name = "echo";
  o.param("prefix", std::string("echo: "));
  auto node = rig.add("demo", "echo", o);
  EXPECT_EQ(node->type_name(), "demo/echo");
  EXPECT_EQ(rig.ctx->clock().now(), bus::Time::from_seconds(10.0));

  auto in = rig.io->create_publisher<StringMsg>("in");
  in->publish(text("a"));
  in->publish(text("b"));
  EXPECT_TRUE(out.empty());  // nothing runs until the test steps the executor
  rig.ex.spin_until_idle();
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0]->data, "echo: a");
  EXPECT_EQ(out[1]->data, "echo: b");

  rig.ex.advance_to(bus::Time::from_seconds(10.35));  // ticks at +0.1, +0.2, +0.3 s
  ASSERT_EQ(ticks.size(), 3u);
  EXPECT_EQ(ticks.back()->data, "tick 3");

  in->publish(text(""));
  rig.ex.spin_until_idle();
  EXPECT_EQ(out.size(), 2u);
  EXPECT_TRUE(rig.log->contains(bus::LogLevel::Warn, "empty text on 'in'"));
}

TEST(NodeRig, UnknownTypesAndBadParametersThrowFromAdd) {
  bus::testing::NodeRig rig({&register_echo});
  bus::NodeOptions o;
  o.name = "x";
  EXPECT_THROW(rig.add("demo", "nope", o), bus::ParamError);
  o.param("prefix", 3.0);  // a double where a string is declared
  EXPECT_THROW(rig.add("demo", "echo", o), bus::ParamError);
}

TEST(NodeRig, AcceptsANodeTheTestBuiltItself) {
  bus::testing::NodeRig rig;
  auto& out = rig.collect<StringMsg>("out");
  bus::NodeOptions o;
  o.name = "mine";
  o.context = rig.ctx;
  rig.add(std::make_shared<EchoNode>(o));
  rig.io->create_publisher<StringMsg>("in")->publish(text("c"));
  rig.ex.spin_until_idle();
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0]->data, ">c");
}
