// Launch files: structure, substitutions, namespaces, parameter files, and a
// golden error message for every way a launch file can be wrong.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <tinyline/launch/launch.hpp>
#include <tinyline/msg/std_msgs/string.hpp>

using namespace tinyline;
namespace fs = std::filesystem;

namespace {

class Talker : public bus::Node {
 public:
  explicit Talker(bus::NodeOptions o) : Node(std::move(o)) {
    rate = declare_parameter("rate_hz", 10.0, "publish rate [Hz]", bus::ParamConstraints::range(0.1, 1000.0));
    text = declare_parameter<std::string>("text", "hello", "what to say");
    count = declare_parameter("count", 0, "messages to send (0: forever)", bus::ParamConstraints::at_least(0));
    pub = create_publisher<std_msgs::msg::String>("chatter");
  }
  double rate;
  std::string text;
  int count;
  std::shared_ptr<bus::Publisher<std_msgs::msg::String>> pub;
};

class Listener : public bus::Node {
 public:
  explicit Listener(bus::NodeOptions o) : Node(std::move(o)) {
    sub = create_subscription<std_msgs::msg::String>("chatter", bus::QoS::keep_last(10), [](const auto&) {});
  }
  std::shared_ptr<bus::Subscription<std_msgs::msg::String>> sub;
};

bus::NodeRegistry registry() {
  bus::NodeRegistry r;
  r.add<Talker>("demo", "talker", "says things");
  r.add<Listener>("demo", "listener", "hears things");
  return r;
}

std::shared_ptr<bus::Context> context() {
  bus::ContextOptions o;
  o.clock = bus::ClockType::Sim;
  o.log_sink = std::make_shared<bus::CaptureSink>();
  return bus::Context::create(o);
}

std::string read(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  std::string t = s.str();
  while (!t.empty() && t.back() == '\n') t.pop_back();
  return t;
}

/// Runs the launch tests from the folder that holds golden/, so messages name
/// files the way a user typing a relative path sees them.
class LaunchTest : public ::testing::Test {
 protected:
  void SetUp() override {
    old_ = fs::current_path();
    fs::current_path(fs::path(TINYLINE_SOURCE_DIR) / "bus/launch/test");
  }
  void TearDown() override { fs::current_path(old_); }
  fs::path old_;
};

}  // namespace

TEST_F(LaunchTest, GoldenErrorMessages) {
  const auto reg = registry();
  int checked = 0;
  for (const auto& entry : fs::directory_iterator("golden")) {
    if (entry.path().extension() != ".expected") continue;
    const std::string stem = entry.path().stem().string();
    const std::string file = "golden/" + stem + ".launch.yaml";
    const std::string expected = read(entry.path());
    std::string got = "no error";
    try {
      auto plan = launch::load_launch_file(file);
      auto nodes = launch::instantiate(plan, reg, context());
    } catch (const launch::LaunchError& e) {
      got = e.what();
    }
    EXPECT_EQ(got, expected) << "for " << file;
    ++checked;
  }
  EXPECT_EQ(checked, 12);
}

TEST_F(LaunchTest, ArgsSubstitutionsGroupsAndRemaps) {
  ::setenv("TINYLINE_TEST_TEXT", "from env", 1);
  const std::string yaml = R"YAML(
launch:
- arg: {name: rate, default: "20.0", description: "publish rate"}
- arg: {name: robot}
- let: {name: greeting, value: "$(env TINYLINE_TEST_TEXT)"}
- node:
    pkg: demo
    exec: talker
    name: t1
    param:
    - {name: rate_hz, value: "$(var rate)"}
    - {name: text, value: "$(var greeting)"}
    - {name: count, value: "$(env TINYLINE_UNSET_VAR 7)"}
    remap:
    - {from: chatter, to: /shared/chatter}
- group:
  - push-ros-namespace: {namespace: "$(var robot)"}
  - node: {pkg: demo, exec: listener, name: l1, remap: [{from: chatter, to: /shared/chatter}]}
  - group:
      namespace: hand
      children:
      - node: {pkg: demo, exec: talker, name: t2}
- node: {pkg: demo, exec: listener, name: top}
)YAML";
  launch::LoadOptions opts;
  opts.args = {{"robot", "hrp2"}};
  auto plan = launch::load_launch_string(yaml, "inline.yaml", opts);
  ASSERT_EQ(plan.nodes.size(), 4u);
  EXPECT_EQ(plan.nodes[1].ns, "/hrp2");
  EXPECT_EQ(plan.nodes[2].ns, "/hrp2/hand");
  EXPECT_EQ(plan.nodes[3].ns, "/");  // the group's namespace does not leak
  ASSERT_EQ(plan.args.size(), 2u);
  EXPECT_EQ(plan.args[0].description, "publish rate");
  auto ctx = context();
  auto nodes = launch::instantiate(plan, registry(), ctx);
  auto* t1 = dynamic_cast<Talker*>(nodes[0].get());
  ASSERT_NE(t1, nullptr);
  EXPECT_DOUBLE_EQ(t1->rate, 20.0);
  EXPECT_EQ(t1->text, "from env");
  EXPECT_EQ(t1->count, 7);
  EXPECT_EQ(t1->pub->topic_name(), "/shared/chatter");
  EXPECT_EQ(nodes[2]->full_name(), "/hrp2/hand/t2");
  auto topics = ctx->graph().topics();
  ASSERT_EQ(topics.size(), 3u);
  EXPECT_EQ(topics[0].name, "/chatter");
  EXPECT_EQ(topics[1].name, "/hrp2/hand/chatter");
  EXPECT_EQ(topics[2].name, "/shared/chatter");
  EXPECT_EQ(topics[2].subscriptions, 1u);
}

TEST_F(LaunchTest, UndeclaredCommandLineArgumentIsRejected) {
  launch::LoadOptions opts;
  opts.args = {{"rat", "5"}};
  try {
    launch::load_launch_string("launch:\n- arg: {name: rate, default: '1'}\n", "x.yaml", opts);
    FAIL();
  } catch (const launch::LaunchError& e) {
    EXPECT_STREQ(e.what(), "x.yaml: launch argument 'rat' is not declared by this file (declared: rate)");
  }
}

TEST_F(LaunchTest, IncludesPassArgumentsAndParamFilesApply) {
  const fs::path dir = fs::temp_directory_path() / "tinyline_launch_test";
  fs::create_directories(dir);
  std::ofstream(dir / "params.yaml") << "/**:\n  ros__parameters:\n    count: 1\n/robot/t:\n  ros__parameters:\n"
                                        "    count: 5\n    text: from file\n";
  std::ofstream(dir / "inner.launch.yaml") << "launch:\n- arg: {name: who}\n- node:\n    pkg: demo\n    exec: talker\n"
                                              "    name: t\n    namespace: $(var who)\n"
                                              "    param: [{from: params.yaml}, {name: rate_hz, value: 2.5}]\n";
  std::ofstream(dir / "outer.launch.yaml") << "launch:\n- include:\n    file: inner.launch.yaml\n"
                                              "    arg: [{name: who, value: robot}]\n";
  auto plan = launch::load_launch_file((dir / "outer.launch.yaml").string());
  ASSERT_EQ(plan.files.size(), 2u);
  auto nodes = launch::instantiate(plan, registry(), context());
  auto* t = dynamic_cast<Talker*>(nodes.at(0).get());
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->full_name(), "/robot/t");
  EXPECT_EQ(t->count, 5);  // node-specific entry beats the wildcard
  EXPECT_EQ(t->text, "from file");
  EXPECT_DOUBLE_EQ(t->rate, 2.5);
  // Where a parameter came from is kept, for errors and `describe`.
  for (const auto& p : t->parameters()) {
    if (p.name == "text") {
      EXPECT_EQ(p.set_from.file, (dir / "params.yaml").string());
    }
  }
  fs::remove_all(dir);
}

TEST_F(LaunchTest, ProcessGroupsSelectTheirNodes) {
  const std::string yaml = R"YAML(
launch:
- node: {pkg: demo, exec: talker, name: here}
- group:
    process: ground
    children:
    - node: {pkg: demo, exec: listener, name: there, respawn: true}
)YAML";
  auto plan = launch::load_launch_string(yaml, "p.yaml");
  EXPECT_EQ(plan.nodes[1].process, "ground");
  EXPECT_TRUE(plan.nodes[1].respawn);
  EXPECT_EQ(launch::instantiate(plan, registry(), context(), "").size(), 1u);
  EXPECT_EQ(launch::instantiate(plan, registry(), context(), "ground").size(), 1u);
}

TEST_F(LaunchTest, DdsMarksNodesGroupsAndTopicsAndIsInheritedIntoIncludes) {
  const fs::path dir = fs::temp_directory_path() / ("tl_launch_dds_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  {
    std::ofstream(dir / "inner.launch.yaml") << "launch:\n- node: {pkg: demo, exec: listener, name: inner}\n";
    std::ofstream(dir / "net.xml") << "<CycloneDDS/>\n";
    std::ofstream(dir / "top.launch.yaml") << R"YAML(launch:
- dds: {topics: [/chatter, /other], domain_id: 7, config: net.xml}
- node: {pkg: demo, exec: talker, name: plain}
- node: {pkg: demo, exec: talker, name: marked, dds: true}
- group:
    process: ground
    dds: true
    children:
    - node: {pkg: demo, exec: listener, name: in_group}
    - node: {pkg: demo, exec: listener, name: opted_out, dds: false}
    - include: {file: inner.launch.yaml}
)YAML";
  }
  const auto plan = launch::load_launch_file((dir / "top.launch.yaml").string());
  ASSERT_EQ(plan.nodes.size(), 5u);
  EXPECT_FALSE(plan.nodes[0].dds);
  EXPECT_TRUE(plan.nodes[1].dds);
  EXPECT_TRUE(plan.nodes[2].dds);
  EXPECT_EQ(plan.nodes[2].process, "ground");
  EXPECT_FALSE(plan.nodes[3].dds);
  EXPECT_TRUE(plan.nodes[4].dds) << "an include inherits the group's dds";
  EXPECT_EQ(plan.nodes[4].process, "ground");
  EXPECT_FALSE(plan.dds.all);
  EXPECT_EQ(plan.dds.topics, (std::vector<std::string>{"/chatter", "/other"}));
  EXPECT_EQ(plan.dds.domain_id, 7);
  EXPECT_EQ(plan.dds.config, "file://" + (dir / "net.xml").lexically_normal().string());
  EXPECT_TRUE(plan.dds.where.known());

  const auto none = launch::load_launch_string("launch:\n- node: {pkg: demo, exec: talker}\n", "n.yaml");
  EXPECT_FALSE(none.dds.where.known());
  EXPECT_FALSE(none.dds.all);
  const auto all = launch::load_launch_string("launch:\n- dds: {topics: all}\n", "a.yaml");
  EXPECT_TRUE(all.dds.all);
  EXPECT_THROW(launch::load_launch_string("launch:\n- dds: {topics: all, port: 3}\n", "k.yaml"), launch::LaunchError);
  EXPECT_THROW(launch::load_launch_string("launch:\n- dds: {config: missing.xml}\n", "m.yaml"), launch::LaunchError);
  EXPECT_THROW(launch::load_launch_string("launch:\n- node: {pkg: demo, exec: talker, dds: maybe}\n", "b.yaml"),
               launch::LaunchError);
  fs::remove_all(dir);
}
