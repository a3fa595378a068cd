// SPDX-License-Identifier: Apache-2.0
// Launch files: structure, substitutions, namespaces, parameter files, and a
// golden error message for every way a launch file can be wrong.
#include <gtest/gtest.h>

#include <unistd.h>

#include <fcntl.h>
#include <sys/stat.h>

#include <cstdlib>
#include <filesystem>
#include <functional>
#include <future>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

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

// Reads a file when it starts (like a driver's calibration or a simulator's
// scene) and writes one (like a recorder); its configure step fails on a
// file that says "broken".
class FileUser : public bus::Node {
 public:
  explicit FileUser(bus::NodeOptions o) : Node(std::move(o)) {
    in = declare_parameter<std::string>("input", "default", "a file it reads (or 'default')",
                                        bus::ParamConstraints::input_file(1024, {"default", "builtin:"}));
    out = declare_parameter<std::string>("output", "", "a file it writes", bus::ParamConstraints::output_file());
  }
  void on_configure() override {
    if (in != "default" && in.rfind("builtin:", 0) != 0) {
      std::ifstream f(in);
      std::string word;
      f >> word;
      if (word == "broken") throw std::runtime_error("'" + in + "' is broken");
    }
  }
  std::string in, out;
};

bus::NodeRegistry registry() {
  bus::NodeRegistry r;
  r.add<Talker>("demo", "talker", "says things");
  r.add<Listener>("demo", "listener", "hears things");
  r.add<FileUser>("demo", "file_user", "reads and writes files");
  return r;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const launch::LaunchError& e) {
    return e.what();
  }
  return "no error";
}

fs::path scratch(const std::string& name) {
  const fs::path d = fs::path(TINYLINE_BINARY_DIR) / "launch_test" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// Loads `path` on another thread: a FIFO must be refused, not waited on. A
// reader that does block is let go (a writer opens the FIFO) so the test fails
// instead of hanging.
std::string load_with_deadline(const std::string& path, const std::string& fifo) {
  auto f = std::async(std::launch::async, [&] { return error_of([&] { (void)launch::load_launch_file(path); }); });
  if (f.wait_for(std::chrono::seconds(30)) != std::future_status::ready) {
    const int w = ::open(fifo.c_str(), O_WRONLY);
    if (w >= 0) ::close(w);
    return "blocked on the FIFO: " + f.get();
  }
  return f.get();
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
  EXPECT_EQ(checked, 18);
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

TEST_F(LaunchTest, DdsSharedMemoryIsAskedForByAnyDdsActionAndMustBeABool) {
  EXPECT_FALSE(launch::load_launch_string("launch:\n- dds: {topics: all}\n", "a.yaml").dds.shared_memory);
  const auto on =
      launch::load_launch_string("launch:\n- dds: {shared_memory: true}\n- dds: {shared_memory: false}\n", "s.yaml");
  EXPECT_TRUE(on.dds.shared_memory) << "a later false does not undo an earlier true";
  EXPECT_NE(error_of([] {
              (void)launch::load_launch_string("launch:\n- dds: {shared_memory: often}\n", "b.yaml");
            }).find("b.yaml:2:"),
            std::string::npos);
}

TEST_F(LaunchTest, AFifoOrADeviceAsLaunchFileIncludeOrParamFileIsRefusedNamingIt) {
  const fs::path d = scratch("fifo");
  const std::string fifo = (d / "pipe.yaml").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(load_with_deadline(fifo, fifo), "launch file '" + fifo + "' is a FIFO, not a regular file");
  std::ofstream(d / "top.launch.yaml") << "launch:\n- include: {file: pipe.yaml}\n";
  const std::string top = (d / "top.launch.yaml").string();
  EXPECT_EQ(load_with_deadline(top, fifo), top + ":2:12: launch file '" + fifo + "' is a FIFO, not a regular file");
  std::ofstream(d / "params.launch.yaml") << "launch:\n- node: {pkg: demo, exec: talker, param: [{from: pipe.yaml}]}\n";
  const std::string params = (d / "params.launch.yaml").string();
  EXPECT_EQ(load_with_deadline(params, fifo),
            params + ":2:50: parameter file '" + fifo + "' is a FIFO, not a regular file");
  // /dev/zero has no end: it used to be read until memory ran out.
  EXPECT_EQ(error_of([] { (void)launch::load_launch_file("/dev/zero"); }),
            "launch file '/dev/zero' is a character device, not a regular file");
  std::ofstream(d / "zero.launch.yaml") << "launch:\n- include: {file: /dev/zero}\n";
  EXPECT_NE(error_of([&] {
              (void)launch::load_launch_file((d / "zero.launch.yaml").string());
            }).find(":2:12: launch file '/dev/zero' is a character device"),
            std::string::npos);
  std::ofstream(d / "big.launch.yaml") << "launch: []\n# " << std::string(2 << 20, 'x') << "\n";
  EXPECT_NE(error_of([&] {
              (void)launch::load_launch_file((d / "big.launch.yaml").string());
            }).find("more than the limit of 1048576"),
            std::string::npos);
}

TEST_F(LaunchTest, ThousandsOfChainedIncludesStopAtTheDepthLimitWithAClearMessage) {
  // 2,500 files, each including the next: the loader recursed until the stack overflowed.
  const fs::path d = scratch("chain");
  constexpr int kFiles = 2500;
  for (int i = 0; i < kFiles; ++i) {
    std::ofstream(d / fmt::format("f{}.launch.yaml", i))
        << (i + 1 < kFiles ? fmt::format("launch:\n- include: {{file: f{}.launch.yaml}}\n", i + 1) : "launch: []\n");
  }
  const std::string e = error_of([&] { (void)launch::load_launch_file((d / "f0.launch.yaml").string()); });
  EXPECT_NE(e.find("f31.launch.yaml:2:12: includes nest deeper than 32 files"), std::string::npos) << e;
  EXPECT_NE(e.find("the include depth limit"), std::string::npos) << e;
  launch::LoadOptions deeper;
  deeper.max_include_depth = 100;  // the limit is an option: the first 99 load, the 100th is refused
  const std::string e2 = error_of([&] { (void)launch::load_launch_file((d / "f0.launch.yaml").string(), deeper); });
  EXPECT_NE(e2.find("f99.launch.yaml:2:12: includes nest deeper than 100 files"), std::string::npos) << e2;
}

TEST_F(LaunchTest, ManyLargeSubstitutionsStopAtTheTotalExpansionLimit) {
  // Each value stays under the per-value limit; together they would not.
  std::string yaml = "launch:\n- let: {name: a, value: \"" + std::string(60000, 'x') + "\"}\n";
  for (int i = 0; i < 400; ++i) yaml += fmt::format("- let: {{name: v{}, value: \"$(var a)\"}}\n", i);
  const std::string e = error_of([&] { (void)launch::load_launch_string(yaml, "wide.yaml"); });
  EXPECT_NE(e.find("substitutions produced more than 16777216 bytes in this launch"), std::string::npos) << e;
  std::string deep = "x";
  for (int i = 0; i < 40; ++i) deep = "$(var " + deep + ")";
  EXPECT_NE(error_of([&] {
              (void)launch::load_launch_string("launch:\n- let: {name: a, value: \"" + deep + "\"}\n", "deep.yaml");
            }).find("substitutions nest deeper than 16 levels"),
            std::string::npos);
}

TEST_F(LaunchTest, AParameterFileWithARepeatedKeyOrASecondDocumentIsAnError) {
  const fs::path d = scratch("params");
  std::ofstream(d / "dup.yaml") << "/**:\n  ros__parameters:\n    count: 1\n    count: 2\n";
  std::ofstream(d / "docs.yaml")
      << "/**:\n  ros__parameters:\n    count: 1\n---\n/**:\n  ros__parameters:\n    count: 2\n";
  EXPECT_EQ(error_of([&] { (void)launch::load_param_file((d / "dup.yaml").string(), "/t"); }),
            (d / "dup.yaml").string() + ":4:5: key 'count' given twice in ros__parameters (first at line 3)");
  EXPECT_EQ(error_of([&] { (void)launch::load_param_file((d / "docs.yaml").string(), "/t"); }),
            (d / "docs.yaml").string() + ":4:1: a second YAML document ('---'): a parameter file holds one");
}

TEST_F(LaunchTest, AMissingInputFileStopsTheLaunchAtTheLineThatNamesIt) {
  // A node's input (a calibration, a scene) that is not there used to pass
  // --check and fail only when the node started, after others had begun.
  const fs::path d = scratch("inputs");
  std::ofstream(d / "ok.txt") << "fine\n";
  std::ofstream(d / "broken.txt") << "broken\n";
  const std::string yaml =
      "launch:\n- arg: {name: in}\n- node:\n    pkg: demo\n    exec: file_user\n"
      "    param: [{name: input, value: \"$(var in)\"}]\n";
  auto build = [&](const std::string& in) {
    launch::LoadOptions o;
    o.args = {{"in", in}};
    const auto plan = launch::load_launch_string(yaml, "in.yaml", o);
    const auto nodes = launch::instantiate(plan, registry(), context());
    launch::configure(plan, nodes);
  };
  EXPECT_EQ(error_of([&] { build((d / "missing.txt").string()); }),
            "in.yaml:6:34: node '/file_user' (demo/file_user): parameter 'input': file '" +
                (d / "missing.txt").string() + "': cannot open: No such file or directory");
  EXPECT_NE(error_of([&] { build("/dev/zero"); })
                .find("in.yaml:6:34: node '/file_user' (demo/file_user): parameter "
                      "'input': file '/dev/zero' is a character device"),
            std::string::npos);
  EXPECT_EQ(error_of([&] { build((d / "ok.txt").string()); }), "no error");
  EXPECT_EQ(error_of([&] { build("default"); }), "no error");
  EXPECT_EQ(error_of([&] { build("builtin:x"); }), "no error");
  EXPECT_EQ(
      error_of([&] { build((d / "broken.txt").string()); }),
      "in.yaml:4:5: node '/file_user' (demo/file_user) cannot start: '" + (d / "broken.txt").string() + "' is broken");
}

TEST_F(LaunchTest, TwoNodesWritingOneFileOrOneWritingAnothersInputAreRefused) {
  const fs::path d = scratch("outputs");
  std::ofstream(d / "in.txt") << "fine\n";
  auto check = [&](const std::string& yaml) {
    const auto plan = launch::load_launch_string(yaml, "out.yaml");
    launch::check_files(launch::instantiate(plan, registry(), context()));
  };
  const std::string out = (d / "out.mcap").string();
  const std::string same = (d / "." / "out.mcap").string();
  EXPECT_EQ(error_of([&] {
              check("launch:\n- node: {pkg: demo, exec: file_user, name: a, param: [{name: output, value: " + out +
                    "}]}\n- node: {pkg: demo, exec: file_user, name: b, param: [{name: output, value: " + same +
                    "}]}\n");
            }),
            "out.yaml:3:77: node '/b' writes '" + same +
                "' (output), which node '/a' writes too (its output at "
                "out.yaml:2:77)");
  const std::string in = (d / "in.txt").string();
  EXPECT_NE(error_of([&] {
              check("launch:\n- node: {pkg: demo, exec: file_user, name: a, param: [{name: input, value: " + in +
                    "}]}\n- node: {pkg: demo, exec: file_user, name: b, param: [{name: output, value: " + in + "}]}\n");
            }).find("node '/b' would write"),
            std::string::npos);
  EXPECT_EQ(error_of([&] {
              check("launch:\n- node: {pkg: demo, exec: file_user, name: a, param: [{name: output, value: " + out +
                    "}]}\n- node: {pkg: demo, exec: file_user, name: b, param: [{name: output, value: " + out +
                    "2}]}\n");
            }),
            "no error");
}

TEST_F(LaunchTest, AParameterFileEntryThatIsNoMappingIsAnErrorWithItsLine) {
  // Found by the fuzzer: indexing the scalar threw yaml-cpp's BadSubscript,
  // which reached the user as "error: yaml-cpp: ..." without the file.
  const fs::path d = scratch("scalar_entry");
  std::ofstream(d / "p.yaml") << "/t:\n  just text\n";
  EXPECT_EQ(error_of([&] { (void)launch::load_param_file((d / "p.yaml").string(), "/t"); }),
            (d / "p.yaml").string() + ":2:3: entry '/t' needs a 'ros__parameters' mapping");
}

TEST_F(LaunchTest, AnInvalidGroupNamespaceIsAnErrorAtItsLine) {
  // Found by the fuzzer: the group's namespace was checked only at a node
  // without one of its own, whose missing 'namespace' key then threw
  // yaml-cpp's InvalidNode ("error: invalid node") instead of a located error.
  const std::string yaml =
      "launch:\n- group:\n    namespace: \"bad-ns\"\n    children:\n"
      "    - node: {pkg: demo, exec: talker}\n";
  EXPECT_EQ(error_of([&] { (void)launch::load_launch_string(yaml, "g.yaml"); }),
            "g.yaml:3:16: namespace '/bad-ns' is invalid: character '-' is not allowed (letters, digits, '_' and '/')");
}

TEST_F(LaunchTest, NodeArgsSetParametersAsRos2FlagsAndAreCheckedAtTheirLine) {
  // ROS 2's `args: "--flag value"` of a node entry: each flag is the
  // parameter of that name (dashes as underscores), substitutions applied.
  const std::string yaml =
      "launch:\n- arg: {name: rate, default: '25.0'}\n- node:\n    pkg: demo\n    exec: talker\n"
      "    args: \"--rate-hz $(var rate) --text hi --count 3\"\n";
  const auto plan = launch::load_launch_string(yaml, "args.yaml");
  const auto nodes = launch::instantiate(plan, registry(), context());
  ASSERT_EQ(nodes.size(), 1u);
  const auto& t = dynamic_cast<const Talker&>(*nodes[0]);
  EXPECT_DOUBLE_EQ(t.rate, 25.0);
  EXPECT_EQ(t.text, "hi");
  EXPECT_EQ(t.count, 3);

  auto error = [&](const std::string& args) {
    return error_of([&] {
      const auto p = launch::load_launch_string(
          "launch:\n- node:\n    pkg: demo\n    exec: talker\n    args: \"" + args + "\"\n", "bad.yaml");
      (void)launch::instantiate(p, registry(), context());
    });
  };
  EXPECT_EQ(error("--rate-hz"), "bad.yaml:5:11: args: --rate-hz needs a value");
  EXPECT_EQ(error("20"),
            "bad.yaml:5:11: args: expected a --flag before '20' (positional arguments are not supported; give each "
            "value as --flag value)");
  EXPECT_NE(error("--rate-hz 5000").find("bad.yaml:5:11"), std::string::npos) << error("--rate-hz 5000");
  EXPECT_NE(error("--volume 3").find("volume"), std::string::npos) << error("--volume 3");
}
