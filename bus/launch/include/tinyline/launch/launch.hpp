// SPDX-License-Identifier: Apache-2.0
// Launch files: YAML in the shape of ROS 2 YAML launch files.
//
//   launch:
//   - arg: {name: scene, default: "rail.yaml", description: "scene to simulate"}
//   - include: {file: "$(dirname)/sensor.launch.yaml", arg: [{name: ns, value: hand}]}
//   - group:
//     - push-ros-namespace: {namespace: robot}
//     - node:
//         pkg: laser_clustering
//         exec: line_clusterer
//         name: clusterer
//         namespace: hand
//         param: [{name: eps_m, value: 0.02}, {from: "$(dirname)/params.yaml"}]
//         remap: [{from: scan, to: /hand/line_scan}]
//
// Process groups and DDS (docs/dds.md):
//
//   - group: {process: ground, dds: true, children: [...]}   # own process; its topics on DDS
//   - node: {pkg: ..., exec: ..., process: ground, dds: true}
//   - dds: {topics: all | [/scan, /clusters], domain_id: 3, config: "$(dirname)/net.xml", shared_memory: true}
//
// Topics that cross process groups always travel over DDS; `dds` marks more
// (every topic of a node or group, named topics, or all) so other programs
// (tinyline topic, ROS 2 nodes) see them.
//
// Substitutions: $(var name), $(env NAME), $(env NAME default), $(dirname),
// $(find-pkg-share pkg). Every key is checked: an unknown or repeated key, a
// second YAML document, a missing required arg, an include cycle, an unknown
// node type or parameter, a wrong type or a value out of range stops the
// launch with the file, line and reason. Nothing starts until the whole file
// is valid.
//
// What a file can make us do is bounded (LoadOptions): every file read must
// be a regular file within a size limit (a FIFO or /dev/zero is refused),
// includes nest only so deep, and substitutions produce only so many bytes
// (nested `let` values cannot expand a small file to gigabytes).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <tinyline/bus/names.hpp>
#include <tinyline/bus/node.hpp>
#include <tinyline/bus/params.hpp>
#include <tinyline/bus/registry.hpp>

namespace tinyline::launch {

/// A problem in a launch file, located ("file:line:col: what").
class LaunchError : public std::runtime_error {
 public:
  LaunchError(const bus::SourceLocation& where, const std::string& what)
      : std::runtime_error(where.known() ? where.str() + ": " + what : what), where_(where) {}
  const bus::SourceLocation& where() const { return where_; }

 private:
  bus::SourceLocation where_;
};

struct ArgDecl {
  std::string name;
  bool has_default = false;
  std::string default_value;
  std::string description;
  bus::SourceLocation where;
};

struct NodeSpec {
  std::string pkg;
  std::string exec;
  std::string name;      ///< defaults to exec
  std::string ns = "/";  ///< with every enclosing group's namespace applied
  std::vector<bus::ParamOverride> params;
  std::vector<bus::Remap> remaps;
  std::string process;             ///< process group ("" = the launching process)
  bool respawn = false;            ///< restart its process if it dies (process groups only)
  bool dds = false;                ///< every topic of this node also travels over DDS
  bus::SourceLocation where;       ///< the node entry
  bus::SourceLocation exec_where;  ///< its exec value (for unknown types)
};

/// The file's `dds` actions, merged.
struct DdsPlan {
  bool all = false;                 ///< every topic travels over DDS
  std::vector<std::string> topics;  ///< these (absolute names) travel over DDS
  std::optional<int> domain_id;     ///< overrides ROS_DOMAIN_ID
  std::string config;               ///< Cyclone DDS configuration (XML or file:// URI); overrides CYCLONEDDS_URI
  /// Large messages to processes on this machine through shared memory:
  /// `tinyline launch` runs a RouDi for the launch if none runs (docs/dds.md).
  bool shared_memory = false;
  bus::SourceLocation where;  ///< the first dds action (empty if none)
};

struct LaunchPlan {
  std::vector<ArgDecl> args;  ///< arguments of the top-level file
  std::vector<NodeSpec> nodes;
  DdsPlan dds;
  std::vector<std::string> files;  ///< every file read, top-level first
};

struct LoadOptions {
  std::map<std::string, std::string> args;  ///< name:=value from the command line
  /// Where $(find-pkg-share pkg) points (tinyline's share dir for every package).
  std::string share_dir;
  /// Reads a launch, include or parameter file; `what` names its role for
  /// messages. Empty: a regular file of at most max_file_bytes
  /// (files::read_text). Tests and the fuzzer serve files from memory.
  std::function<std::string(const std::string& path, std::string_view what)> read_file;
  std::uint64_t max_file_bytes = 1 << 20;       ///< a launch, include or parameter file [bytes]
  int max_include_depth = 32;                   ///< files open at once (the top file counts)
  std::size_t max_value_bytes = 64 << 10;       ///< one value after substitution [bytes]
  std::uint64_t max_expanded_bytes = 16 << 20;  ///< all substitution output of one load [bytes]
  int max_substitution_depth = 16;              ///< $( inside $( inside ...
};

/// Reads a launch file and everything it includes. Throws LaunchError.
LaunchPlan load_launch_file(const std::string& path, const LoadOptions& options = {});
LaunchPlan load_launch_string(const std::string& yaml, const std::string& source_name, const LoadOptions& options = {});

/// Builds every node of the plan in `context` (those of `process` only).
/// Throws LaunchError naming the launch-file entry: unknown node type (with
/// the known ones), unknown parameter, wrong type, out of range, duplicate
/// node name.
std::vector<std::shared_ptr<bus::Node>> instantiate(const LaunchPlan& plan, const bus::NodeRegistry& registry,
                                                    const std::shared_ptr<bus::Context>& context,
                                                    const std::string& process = "");

/// Calls on_configure() of each node (those of `process`, as instantiate()
/// returned them), so unusable inputs (a calibration that does not load)
/// stop the launch before anything starts. Throws LaunchError at the node's entry.
void configure(const LaunchPlan& plan, const std::vector<std::shared_ptr<bus::Node>>& nodes,
               const std::string& process = "");

/// Checks the files the nodes name in their parameters
/// (bus::ParamConstraints::File): no two nodes write one file, and no node
/// writes a file another node reads. Throws LaunchError at the line that set
/// the parameter.
void check_files(const std::vector<std::shared_ptr<bus::Node>>& nodes);

/// Reads a ROS 2 parameter file (`node: {ros__parameters: {...}}`, `/**` for
/// all nodes) and returns the overrides for the node with this full name.
/// The file is read as options.read_file says; a repeated key is an error.
std::vector<bus::ParamOverride> load_param_file(const std::string& path, const std::string& node_full_name,
                                                const LoadOptions& options = {});

}  // namespace tinyline::launch
