// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: arbitrary bytes as a launch file and the files it
// includes or reads parameters from, served from memory. The input is split
// at NUL bytes into top.launch.yaml, a.yaml, b.yaml and c.yaml (in /fuzz/).
// Properties beyond "no crash, no sanitizer report, no hang, bounded
// memory": every failure is a LaunchError with a message, and a plan that
// loads builds its nodes or says why.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>

#include <tinyline/launch/launch.hpp>

using namespace tinyline;

namespace {

// A node type with a parameter of each kind, and a file it reads and one it writes.
class Probe : public bus::Node {
 public:
  explicit Probe(bus::NodeOptions o) : Node(std::move(o)) {
    (void)declare_parameter("rate_hz", 10.0, "a rate [Hz]", bus::ParamConstraints::range(0.1, 1000.0));
    (void)declare_parameter("count", 0, "a count", bus::ParamConstraints::at_least(0));
    (void)declare_parameter<std::string>("mode", "a", "a choice", bus::ParamConstraints::one_of({"a", "b"}));
    (void)declare_parameter("flag", false, "a switch");
    (void)declare_parameter<std::vector<double>>("gains", {1.0}, "numbers");
    (void)declare_parameter<std::vector<std::string>>("names", {}, "words");
    (void)declare_parameter<std::string>("input", "default", "a file it reads",
                                         bus::ParamConstraints::input_file(1 << 16, {"default"}));
    (void)declare_parameter<std::string>("output", "", "a file it writes", bus::ParamConstraints::output_file());
  }
};

[[noreturn]] void violated(const char* what) {
  std::fprintf(stderr, "property violated: %s\n", what);
  std::abort();
}

std::map<std::string, std::string> split_files(const std::uint8_t* data, std::size_t size) {
  static const char* const kNames[] = {"top.launch.yaml", "a.yaml", "b.yaml", "c.yaml"};
  std::map<std::string, std::string> files;
  std::size_t start = 0, n = 0;
  for (std::size_t i = 0; i <= size && n < 4; ++i) {
    if (i == size || data[i] == 0) {
      files[kNames[n++]] = std::string(reinterpret_cast<const char*>(data) + start, i - start);
      start = i + 1;
    }
  }
  return files;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto files = split_files(data, size);
  launch::LoadOptions lo;
  lo.share_dir = "/fuzz/share";
  lo.read_file = [&files](const std::string& path, std::string_view what) {
    auto it = files.find(std::filesystem::path(path).filename().string());
    if (it == files.end()) throw std::runtime_error(std::string(what) + " '" + path + "': cannot open: no such file");
    return it->second;
  };
  static const bus::NodeRegistry registry = [] {
    bus::NodeRegistry r;
    r.add<Probe>("fuzz", "probe", "a node with one parameter of each kind");
    return r;
  }();
  try {
    const launch::LaunchPlan plan = launch::load_launch_file("/fuzz/top.launch.yaml", lo);
    // The launching process and the first process group, each in a context of its own.
    std::vector<std::string> processes{""};
    for (const auto& spec : plan.nodes) {
      if (!spec.process.empty()) {
        processes.push_back(spec.process);
        break;
      }
    }
    std::vector<std::shared_ptr<bus::Node>> all;
    for (const auto& process : processes) {
      bus::ContextOptions co;
      co.clock = bus::ClockType::Sim;
      co.log_sink = std::make_shared<bus::CaptureSink>();
      auto nodes = launch::instantiate(plan, registry, bus::Context::create(co), process);
      launch::configure(plan, nodes, process);
      all.insert(all.end(), nodes.begin(), nodes.end());
    }
    launch::check_files(all);
  } catch (const launch::LaunchError& e) {
    if (std::string(e.what()).empty()) violated("a LaunchError without a message");
  }
  return 0;
}
