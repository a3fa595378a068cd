// SPDX-License-Identifier: Apache-2.0
#include <tinyline/launch/launch.hpp>

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <sstream>

#include <fmt/format.h>

#include <tinyline/bus/detail/yaml_params.hpp>
#include <tinyline/bus/files.hpp>
#include <tinyline/common/yaml_documents.hpp>

namespace tinyline::launch {

namespace fs = std::filesystem;
using bus::SourceLocation;

namespace {

SourceLocation mark_of(const std::string& file, const YAML::Mark& m) {
  return SourceLocation{file, m.line >= 0 ? m.line + 1 : 0, m.column >= 0 ? m.column + 1 : 0};
}

// A file's text through options.read_file, or the bounded default reader.
std::string read_input(const LoadOptions& o, const std::string& path, std::string_view what,
                       const SourceLocation& from) {
  try {
    if (o.read_file) return o.read_file(path, what);
    return files::read_text(path, what, o.max_file_bytes);
  } catch (const LaunchError&) {
    throw;
  } catch (const std::exception& e) {
    throw LaunchError(from, e.what());
  }
}

// One YAML document: a second one would be ignored silently, so it is an error.
YAML::Node parse_one_document(const std::string& text, const std::string& file, std::string_view what) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
    if (const auto second = common::second_document(text)) {
      throw LaunchError(mark_of(file, *second), fmt::format("a second YAML document ('---'): a {} holds one", what));
    }
  } catch (const YAML::Exception& e) {
    throw LaunchError(mark_of(file, e.mark), "YAML syntax error: " + e.msg);
  }
  return root;
}

// A key given twice in one mapping: yaml-cpp keeps both, lookups see the first.
void check_unique_keys(const YAML::Node& map, const std::string& file, const std::string& what) {
  std::map<std::string, YAML::Mark> seen;
  for (const auto& kv : map) {
    const std::string key = kv.first.Scalar();
    auto [it, fresh] = seen.emplace(key, kv.first.Mark());
    if (!fresh) {
      throw LaunchError(mark_of(file, kv.first.Mark()),
                        fmt::format("key '{}' given twice in {} (first at line {})", key, what, it->second.line + 1));
    }
  }
}

struct Scope {
  std::map<std::string, std::string> vars;
  std::string ns = "/";
  std::string process;
  bool dds = false;
  std::string file;  // as given (for messages)
  std::string dir;   // for $(dirname) and relative includes
};

struct Loader {
  const LoadOptions& options;
  LaunchPlan plan;
  std::vector<std::string> stack;  // absolute paths of files being read (include cycles)
  std::uint64_t expanded = 0;      // bytes produced by substitutions so far

  SourceLocation loc(const Scope& s, const YAML::Node& n) const { return mark_of(s.file, n.Mark()); }

  [[noreturn]] void fail(const Scope& s, const YAML::Node& n, const std::string& what) const {
    throw LaunchError(loc(s, n), what);
  }

  void check_keys(const Scope& s, const YAML::Node& map, const std::vector<std::string>& allowed,
                  const std::string& what) const {
    if (!map.IsMap()) fail(s, map, what + " must be a mapping");
    check_unique_keys(map, s.file, what);
    for (const auto& kv : map) {
      const std::string key = kv.first.Scalar();
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        fail(s, kv.first, fmt::format("unknown key '{}' in {} (allowed: {})", key, what, list));
      }
    }
  }

  // ---------------------------------------------------------------- substitutions

  // The ')' that closes the "$(" at `i`, allowing nested substitutions.
  std::size_t closing(const Scope& s, const YAML::Node& n, const std::string& text, std::size_t i) const {
    int depth = 0;
    for (std::size_t j = i; j < text.size(); ++j) {
      if (text.compare(j, 2, "$(") == 0) {
        ++depth;
        ++j;
      } else if (text[j] == ')' && --depth == 0) {
        return j;
      }
    }
    fail(s, n, "unterminated substitution in '" + text + "'");
  }

  // Keeps every value and the whole load within the expansion limits.
  void account(const Scope& s, const YAML::Node& n, const std::string& out) {
    if (out.size() > options.max_value_bytes) {
      fail(s, n,
           fmt::format("a value grows past {} bytes through substitutions (the expansion limit)",
                       options.max_value_bytes));
    }
    if (expanded > options.max_expanded_bytes) {
      fail(s, n,
           fmt::format("substitutions produced more than {} bytes in this launch (the expansion limit: "
                       "values that nest $(var ...) of each other grow exponentially)",
                       options.max_expanded_bytes));
    }
  }

  std::string var(const Scope& s, const YAML::Node& n, const std::vector<std::string>& argv) const {
    if (argv.size() != 1) fail(s, n, "$(var) takes one name");
    auto it = s.vars.find(argv[0]);
    if (it != s.vars.end()) return it->second;
    std::string known;
    for (const auto& [k, v] : s.vars) known += (known.empty() ? "" : ", ") + k;
    fail(s, n,
         fmt::format("unknown launch argument '{}' in $(var {}) (known: {})", argv[0], argv[0],
                     known.empty() ? "none" : known));
  }

  std::string env(const Scope& s, const YAML::Node& n, const std::vector<std::string>& argv) const {
    if (argv.empty() || argv.size() > 2) fail(s, n, "$(env NAME [default]) takes one or two words");
    if (const char* v = std::getenv(argv[0].c_str())) return v;
    if (argv.size() == 2) return argv[1];
    fail(s, n, fmt::format("environment variable '{}' is not set (give a default: $(env {} value))", argv[0], argv[0]));
  }

  // The text one substitution stands for: `inner` is what is between $( and ).
  std::string evaluate(const Scope& s, const YAML::Node& n, const std::string& inner) const {
    std::istringstream words(inner);
    std::string cmd;
    words >> cmd;
    std::vector<std::string> argv;
    for (std::string w; words >> w;) argv.push_back(w);
    if (cmd == "var") return var(s, n, argv);
    if (cmd == "env") return env(s, n, argv);
    if (cmd == "dirname") return s.dir;
    if (cmd == "find-pkg-share") {
      if (argv.size() != 1) fail(s, n, "$(find-pkg-share) takes one package name");
      if (options.share_dir.empty()) fail(s, n, "$(find-pkg-share) is not available: no share directory configured");
      return options.share_dir;
    }
    fail(s, n, fmt::format("unknown substitution '$({})' (known: var, env, dirname, find-pkg-share)", cmd));
  }

  std::string substitute(const Scope& s, const YAML::Node& n, const std::string& text, int depth = 0) {
    if (depth > options.max_substitution_depth) {
      fail(s, n, fmt::format("substitutions nest deeper than {} levels", options.max_substitution_depth));
    }
    std::string out;
    std::size_t i = 0;
    while (i < text.size()) {
      if (text.compare(i, 2, "$(") != 0) {
        out += text[i++];
        continue;
      }
      const std::size_t j = closing(s, n, text, i);
      const std::string value = evaluate(s, n, substitute(s, n, text.substr(i + 2, j - i - 2), depth + 1));
      expanded += value.size();
      out += value;
      account(s, n, out);
      i = j + 1;
    }
    return out;
  }

  std::string str(const Scope& s, const YAML::Node& n, const std::string& what) {
    if (!n.IsScalar()) fail(s, n, what + " must be a scalar");
    return substitute(s, n, n.Scalar());
  }

  bool boolean(const Scope& s, const YAML::Node& n, const std::string& what) {
    const std::string b = str(s, n, what);
    if (b != "true" && b != "false") fail(s, n, what + " must be true or false");
    return b == "true";
  }

  // ---------------------------------------------------------------- files

  /// An included file's path: relative to the including file, shown relative
  /// to the working directory when it lies below it (as compilers do).
  std::string resolve_path(const Scope& s, const std::string& p) const {
    fs::path path(p);
    if (path.is_relative()) path = fs::path(s.dir) / path;
    return display(path.lexically_normal().string());
  }

  static std::string display(const std::string& p) {
    std::error_code ec;
    const fs::path rel = fs::proximate(fs::path(p), fs::current_path(ec), ec);
    if (ec || rel.empty() || *rel.begin() == "..") return p;
    return rel.string();
  }

  void enter(const std::string& abs, const SourceLocation& from) const {
    if (std::find(stack.begin(), stack.end(), abs) != stack.end()) {
      std::string chain;
      for (const auto& f : stack) chain += display(f) + " -> ";
      throw LaunchError(from, "include cycle: " + chain + display(abs));
    }
    if (static_cast<int>(stack.size()) >= options.max_include_depth) {
      throw LaunchError(from, fmt::format("includes nest deeper than {} files (from {}): the include depth limit",
                                          options.max_include_depth, display(stack.front())));
    }
  }

  void load_file(const std::string& path, std::map<std::string, std::string> given, const Scope& outer,
                 const SourceLocation& from) {
    std::error_code ec;
    const std::string abs = fs::weakly_canonical(fs::path(path), ec).string();
    enter(abs, from);
    const std::string text = read_input(options, path, "launch file", from);
    stack.push_back(abs);
    Scope s;
    s.file = path;
    s.dir = fs::path(abs).parent_path().string();
    s.ns = outer.ns;
    s.process = outer.process;
    s.dds = outer.dds;
    load_text(text, s, std::move(given), stack.size() == 1);
    stack.pop_back();
  }

  void load_text(const std::string& text, Scope& s, std::map<std::string, std::string> given, bool top) {
    plan.files.push_back(s.file);
    const YAML::Node root = parse_one_document(text, s.file, "launch file");
    if (!root.IsMap() || !root["launch"]) {
      throw LaunchError(SourceLocation{s.file, 1, 1}, "a launch file is a mapping with one key, 'launch'");
    }
    check_keys(s, root, {"launch"}, "the launch file");
    const YAML::Node body = root["launch"];
    if (!body.IsSequence()) fail(s, body, "'launch' must be a list of actions");
    std::set<std::string> declared;
    run_actions(s, body, given, declared, top);
    for (const auto& [name, value] : given) {
      if (!declared.count(name)) {
        std::string known;
        for (const auto& d : declared) known += (known.empty() ? "" : ", ") + d;
        throw LaunchError(SourceLocation{s.file, 0, 0},
                          fmt::format("launch argument '{}' is not declared by this file (declared: {})", name,
                                      known.empty() ? "none" : known));
      }
    }
  }

  // ---------------------------------------------------------------- actions

  void run_actions(Scope& s, const YAML::Node& list, std::map<std::string, std::string>& given,
                   std::set<std::string>& declared, bool top) {
    for (const auto& entry : list) {
      if (!entry.IsMap() || entry.size() != 1) {
        fail(s, entry,
             "each action is a mapping with one key: arg, let, include, group, node, dds or push-ros-namespace");
      }
      const std::string kind = entry.begin()->first.Scalar();
      const YAML::Node v = entry.begin()->second;
      if (kind == "arg") {
        action_arg(s, v, given, declared, top);
      } else if (kind == "let") {
        action_let(s, v);
      } else if (kind == "include") {
        action_include(s, v);
      } else if (kind == "group") {
        action_group(s, v, given, declared);
      } else if (kind == "push-ros-namespace" || kind == "push_ros_namespace") {
        action_push_namespace(s, v, kind);
      } else if (kind == "node") {
        action_node(s, v);
      } else if (kind == "dds") {
        action_dds(s, v);
      } else {
        fail(s, entry.begin()->first,
             fmt::format("unknown action '{}' (known: arg, let, include, group, node, dds, push-ros-namespace)", kind));
      }
    }
  }

  void action_arg(Scope& s, const YAML::Node& v, std::map<std::string, std::string>& given,
                  std::set<std::string>& declared, bool top) {
    check_keys(s, v, {"name", "default", "description"}, "arg");
    if (!v["name"]) fail(s, v, "arg needs a name");
    ArgDecl a;
    a.name = str(s, v["name"], "arg name");
    a.where = loc(s, v);
    if (v["description"]) a.description = str(s, v["description"], "description");
    if (v["default"]) {
      a.has_default = true;
      a.default_value = str(s, v["default"], "default");
    }
    declared.insert(a.name);
    auto it = given.find(a.name);
    if (it != given.end()) {
      s.vars[a.name] = it->second;
    } else if (a.has_default) {
      s.vars[a.name] = a.default_value;
    } else {
      fail(s, v,
           fmt::format("missing required launch argument '{}'{} (pass {}:=VALUE)", a.name,
                       a.description.empty() ? "" : " (" + a.description + ")", a.name));
    }
    if (top) plan.args.push_back(a);
  }

  void action_let(Scope& s, const YAML::Node& v) {
    check_keys(s, v, {"name", "value"}, "let");
    if (!v["name"] || !v["value"]) fail(s, v, "let needs name and value");
    s.vars[str(s, v["name"], "let name")] = str(s, v["value"], "let value");
  }

  void action_push_namespace(Scope& s, const YAML::Node& v, const std::string& kind) {
    check_keys(s, v, {"namespace"}, kind);
    if (!v["namespace"]) fail(s, v, kind + " needs a namespace");
    const std::string ns = str(s, v["namespace"], "namespace");
    try {
      s.ns = bus::join_namespace(s.ns, ns);
      if (s.ns != "/") bus::validate_name(s.ns, "namespace");
    } catch (const std::invalid_argument& e) {
      fail(s, v["namespace"], e.what());
    }
  }

  void action_include(Scope& s, const YAML::Node& v) {
    check_keys(s, v, {"file", "arg"}, "include");
    if (!v["file"]) fail(s, v, "include needs a file");
    const std::string file = resolve_path(s, str(s, v["file"], "file"));
    std::map<std::string, std::string> args;
    if (v["arg"]) {
      if (!v["arg"].IsSequence()) fail(s, v["arg"], "include arg must be a list of {name, value}");
      for (const auto& a : v["arg"]) {
        check_keys(s, a, {"name", "value"}, "include arg");
        if (!a["name"] || !a["value"]) fail(s, a, "include arg needs name and value");
        args[str(s, a["name"], "name")] = str(s, a["value"], "value");
      }
    }
    load_file(file, std::move(args), s, loc(s, v));
  }

  void action_group(Scope& s, const YAML::Node& v, std::map<std::string, std::string>& given,
                    std::set<std::string>& declared) {
    Scope inner = s;
    YAML::Node children;
    if (v.IsSequence()) {
      children = v;
    } else {
      check_keys(s, v, {"namespace", "process", "dds", "scoped", "children"}, "group");
      if (!v["children"]) fail(s, v, "group needs children (a list of actions)");
      children = v["children"];
      if (v["namespace"]) {
        try {
          inner.ns = bus::join_namespace(s.ns, str(s, v["namespace"], "namespace"));
          if (inner.ns != "/") bus::validate_name(inner.ns, "namespace");
        } catch (const std::invalid_argument& e) {
          fail(s, v["namespace"], e.what());
        }
      }
      if (v["process"]) inner.process = str(s, v["process"], "process");
      if (v["dds"]) inner.dds = boolean(s, v["dds"], "dds");
      if (v["scoped"] && str(s, v["scoped"], "scoped") == "false") {
        run_actions(s, children, given, declared, false);
        return;
      }
    }
    if (!children.IsSequence()) fail(s, children, "group children must be a list of actions");
    run_actions(inner, children, given, declared, false);
  }

  // ---------------------------------------------------------------- node

  void action_node(const Scope& s, const YAML::Node& v) {
    check_keys(s, v,
               {"pkg", "exec", "name", "namespace", "param", "args", "remap", "respawn", "output", "process", "dds"},
               "node");
    NodeSpec n;
    n.where = loc(s, v);
    if (!v["pkg"]) fail(s, v, "node needs pkg");
    if (!v["exec"]) fail(s, v, "node needs exec (the node type)");
    n.pkg = str(s, v["pkg"], "pkg");
    n.exec = str(s, v["exec"], "exec");
    n.exec_where = loc(s, v["exec"]);
    n.name = v["name"] ? str(s, v["name"], "name") : n.exec;
    n.process = v["process"] ? str(s, v["process"], "process") : s.process;
    n.ns = node_namespace(s, v);
    if (v["respawn"]) n.respawn = boolean(s, v["respawn"], "respawn");
    // Frames are for the ROS 2 graph: a static transform publisher's /tf_static
    // goes on DDS unless the entry says otherwise.
    const bool frames = n.pkg == "tf2_ros" && n.exec == "static_transform_publisher";
    n.dds = v["dds"] ? boolean(s, v["dds"], "dds") : s.dds || frames;
    if (v["output"]) {
      const std::string o = str(s, v["output"], "output");
      if (o != "screen" && o != "log") fail(s, v["output"], "output must be screen or log");
    }
    if (v["param"]) n.params = node_params(s, v["param"], (n.ns == "/" ? "" : n.ns) + "/" + n.name);
    if (v["remap"]) n.remaps = node_remaps(s, v["remap"]);
    if (v["args"]) {
      auto from_args = node_args(s, v["args"]);
      n.params.insert(n.params.end(), from_args.begin(), from_args.end());
    }
    plan.nodes.push_back(std::move(n));
  }

  /// ROS 2's command-line arguments of a node, `args: "--x 0.1 --frame-id
  /// base_link"`: each `--flag value` pair sets the parameter `flag` (dashes
  /// read as underscores), typed like a command-line value and located at
  /// the args entry, so the node's declarations check name, type and range.
  std::vector<bus::ParamOverride> node_args(const Scope& s, const YAML::Node& v) {
    std::vector<std::string> tokens;
    std::istringstream in(str(s, v, "args"));
    for (std::string t; in >> t;) tokens.push_back(t);
    std::vector<bus::ParamOverride> out;
    for (std::size_t i = 0; i < tokens.size(); i += 2) {
      const std::string& flag = tokens[i];
      if (flag.size() < 3 || flag.rfind("--", 0) != 0) {
        fail(s, v,
             fmt::format("args: expected a --flag before '{}' (positional arguments are not supported; give "
                         "each value as --flag value)",
                         flag));
      }
      if (i + 1 == tokens.size() || tokens[i + 1].rfind("--", 0) == 0) {
        fail(s, v, fmt::format("args: {} needs a value", flag));
      }
      std::string name = flag.substr(2);
      std::replace(name.begin(), name.end(), '-', '_');
      out.push_back(bus::ParamOverride{name, bus::parse_param_text(tokens[i + 1]), loc(s, v)});
    }
    return out;
  }

  std::string node_namespace(const Scope& s, const YAML::Node& v) {
    try {
      const std::string ns = v["namespace"] ? bus::join_namespace(s.ns, str(s, v["namespace"], "namespace")) : s.ns;
      if (ns != "/") bus::validate_name(ns, "namespace");
      return ns;
    } catch (const std::invalid_argument& e) {
      fail(s, v["namespace"] ? v["namespace"] : v, e.what());
    }
  }

  std::vector<bus::ParamOverride> node_params(const Scope& s, const YAML::Node& list, const std::string& full) {
    if (!list.IsSequence()) fail(s, list, "param must be a list of {name, value} or {from: file}");
    std::vector<bus::ParamOverride> out;
    for (const auto& p : list) {
      if (p.IsMap() && p["from"]) {
        check_keys(s, p, {"from"}, "param");
        const std::string path = resolve_path(s, str(s, p["from"], "from"));
        try {
          auto from_file = load_param_file(path, full, options);
          out.insert(out.end(), from_file.begin(), from_file.end());
        } catch (const LaunchError& e) {
          if (e.where().known()) throw;
          fail(s, p["from"], e.what());  // the file could not be read: at the line that names it
        }
        continue;
      }
      check_keys(s, p, {"name", "value"}, "param");
      if (!p["name"] || !p["value"]) fail(s, p, "param needs name and value");
      out.push_back(
          bus::ParamOverride{str(s, p["name"], "param name"), param_value(s, p["value"]), loc(s, p["value"])});
    }
    return out;
  }

  std::vector<bus::Remap> node_remaps(const Scope& s, const YAML::Node& list) {
    if (!list.IsSequence()) fail(s, list, "remap must be a list of {from, to}");
    std::vector<bus::Remap> out;
    for (const auto& r : list) {
      check_keys(s, r, {"from", "to"}, "remap");
      if (!r["from"] || !r["to"]) fail(s, r, "remap needs from and to");
      bus::Remap rm{str(s, r["from"], "from"), str(s, r["to"], "to")};
      try {
        bus::validate_name(rm.from, "remap source");
        bus::validate_name(rm.to, "remap target");
      } catch (const std::invalid_argument& e) {
        fail(s, r, e.what());
      }
      out.push_back(rm);
    }
    return out;
  }

  bus::ParamValue param_value(const Scope& s, const YAML::Node& n) {
    std::string why;
    if (n.IsScalar() && n.Scalar().find("$(") != std::string::npos) {
      // A substituted value is typed like a command-line value.
      return bus::parse_param_text(substitute(s, n, n.Scalar()));
    }
    if (n.IsSequence()) {
      // Substitute inside list elements, then type the list.
      YAML::Node copy = YAML::Clone(n);
      for (std::size_t i = 0; i < copy.size(); ++i) {
        if (copy[i].IsScalar() && copy[i].Scalar().find("$(") != std::string::npos) {
          copy[i] = substitute(s, n, copy[i].Scalar());
        }
      }
      if (auto v = bus::param_from_yaml(copy, &why)) return *v;
      fail(s, n, "bad parameter value: " + why);
    }
    if (auto v = bus::param_from_yaml(n, &why)) return *v;
    fail(s, n, "bad parameter value: " + why);
  }

  // ---------------------------------------------------------------- dds

  void action_dds(const Scope& s, const YAML::Node& v) {
    check_keys(s, v, {"topics", "domain_id", "config", "shared_memory"}, "dds");
    DdsPlan& d = plan.dds;
    if (!d.where.known()) d.where = loc(s, v);
    if (const YAML::Node t = v["topics"]) dds_topics(s, t);
    if (const YAML::Node id = v["domain_id"]) dds_domain(s, id);
    if (const YAML::Node c = v["config"]) d.config = dds_config(s, c);
    if (const YAML::Node m = v["shared_memory"]) d.shared_memory = d.shared_memory || boolean(s, m, "shared_memory");
  }

  void dds_topics(const Scope& s, const YAML::Node& t) {
    DdsPlan& d = plan.dds;
    if (t.IsScalar()) {
      if (str(s, t, "topics") != "all") fail(s, t, "dds topics must be 'all' or a list of absolute topic names");
      d.all = true;
      return;
    }
    if (!t.IsSequence()) fail(s, t, "dds topics must be 'all' or a list of absolute topic names");
    for (const auto& e : t) {
      const std::string name = str(s, e, "topic");
      try {
        bus::validate_name(name, "dds topic");
      } catch (const std::invalid_argument& ex) {
        fail(s, e, ex.what());
      }
      if (name[0] != '/') fail(s, e, "dds topic '" + name + "' must be absolute (start with '/')");
      if (std::find(d.topics.begin(), d.topics.end(), name) == d.topics.end()) d.topics.push_back(name);
    }
  }

  void dds_domain(const Scope& s, const YAML::Node& id) {
    DdsPlan& d = plan.dds;
    const std::string text = str(s, id, "domain_id");
    char* end = nullptr;
    const long n = std::strtol(text.c_str(), &end, 10);
    if (text.empty() || *end != '\0' || n < 0 || n > 232) {
      fail(s, id, "dds domain_id must be an integer in 0..232, got '" + text + "'");
    }
    if (d.domain_id && *d.domain_id != n) {
      fail(s, id, fmt::format("dds domain_id {} contradicts domain_id {} given at {}", n, *d.domain_id, d.where.str()));
    }
    d.domain_id = static_cast<int>(n);
  }

  // XML text and file:// URIs pass as they are (CYCLONEDDS_URI syntax); a
  // plain path is relative to this launch file and must be a readable file.
  std::string dds_config(const Scope& s, const YAML::Node& c) {
    std::string cfg = str(s, c, "config");
    if (cfg.empty() || cfg[0] == '<' || cfg.rfind("file://", 0) == 0) return cfg;
    fs::path p(cfg);
    if (p.is_relative()) p = fs::path(s.dir) / p;
    try {
      files::check_input(p.lexically_normal().string(), "dds config file", options.max_file_bytes);
    } catch (const files::FileError& e) {
      fail(s, c, e.what());
    }
    std::error_code ec;
    return "file://" + fs::absolute(p, ec).lexically_normal().string();
  }
};

// ---------------------------------------------------------------- parameter files

void flatten(const YAML::Node& n, const std::string& prefix, const std::string& file,
             std::vector<bus::ParamOverride>& out) {
  check_unique_keys(n, file, prefix.empty() ? "ros__parameters" : "'" + prefix + "'");
  for (const auto& kv : n) {
    const std::string key = prefix.empty() ? kv.first.Scalar() : prefix + "." + kv.first.Scalar();
    if (kv.second.IsMap()) {
      flatten(kv.second, key, file, out);
      continue;
    }
    std::string why;
    const SourceLocation where = mark_of(file, kv.second.Mark());
    auto v = bus::param_from_yaml(kv.second, &why);
    if (!v) throw LaunchError(where, "bad parameter value for '" + key + "': " + why);
    out.push_back(bus::ParamOverride{key, *v, where});
  }
}

// ---------------------------------------------------------------- node files

struct FileUse {
  std::string node;
  std::string param;
  SourceLocation where;
};

std::string file_key(const std::string& path) {
  std::error_code ec;
  const fs::path abs = fs::absolute(fs::path(path), ec);
  const fs::path canon = fs::weakly_canonical(abs, ec);
  return (ec ? abs : canon).lexically_normal().string();
}

}  // namespace

std::vector<bus::ParamOverride> load_param_file(const std::string& path, const std::string& node_full_name,
                                                const LoadOptions& options) {
  // A file that cannot be read: the message names it; the caller knows the line.
  const YAML::Node root = parse_one_document(read_input(options, path, "parameter file", {}), path, "parameter file");
  if (!root.IsMap())
    throw LaunchError(SourceLocation{path, 1, 1}, "a parameter file maps node names to ros__parameters");
  check_unique_keys(root, path, "the parameter file");
  const std::string short_name = node_full_name.substr(node_full_name.rfind('/') + 1);
  std::vector<bus::ParamOverride> out;
  // Wildcard first so a node-specific entry wins (the last override wins).
  for (const bool wild_pass : {true, false}) {
    for (const auto& kv : root) {
      const std::string key = kv.first.Scalar();
      const bool wild = key == "/**";
      const bool exact = key == node_full_name || key == short_name || key == node_full_name.substr(1);
      if (wild_pass ? !wild : !exact) continue;
      const YAML::Node params = kv.second.IsMap() ? kv.second["ros__parameters"] : YAML::Node();
      if (!params || !params.IsMap()) {
        throw LaunchError(mark_of(path, kv.second.Mark()), "entry '" + key + "' needs a 'ros__parameters' mapping");
      }
      flatten(params, "", path, out);
    }
  }
  return out;
}

LaunchPlan load_launch_file(const std::string& path, const LoadOptions& options) {
  Loader l{options, {}, {}, 0};
  Scope outer;
  l.load_file(path, options.args, outer, SourceLocation{});  // errors reading it name the file
  return std::move(l.plan);
}

LaunchPlan load_launch_string(const std::string& yaml, const std::string& source_name, const LoadOptions& options) {
  Loader l{options, {}, {}, 0};
  Scope s;
  s.file = source_name;
  s.dir = fs::current_path().string();
  l.stack.push_back(source_name);
  l.load_text(yaml, s, options.args, true);
  return std::move(l.plan);
}

std::vector<std::shared_ptr<bus::Node>> instantiate(const LaunchPlan& plan, const bus::NodeRegistry& registry,
                                                    const std::shared_ptr<bus::Context>& context,
                                                    const std::string& process) {
  std::vector<std::shared_ptr<bus::Node>> nodes;
  std::map<std::string, SourceLocation> seen;
  for (const auto& spec : plan.nodes) {
    if (spec.process != process) continue;
    const std::string full = (spec.ns == "/" ? "" : spec.ns) + "/" + spec.name;
    auto [it, fresh] = seen.emplace(full, spec.where);
    if (!fresh) {
      throw LaunchError(spec.where, fmt::format("duplicate node name '{}' (first at {})", full, it->second.str()));
    }
    if (registry.find(spec.pkg, spec.exec) == nullptr) {
      std::string known;
      for (const auto* t : registry.all()) known += (known.empty() ? "" : ", ") + t->full_name();
      throw LaunchError(
          spec.exec_where.known() ? spec.exec_where : spec.where,
          fmt::format("unknown node type '{}/{}' (known: {})", spec.pkg, spec.exec, known.empty() ? "none" : known));
    }
    bus::NodeOptions o;
    o.name = spec.name;
    o.ns = spec.ns;
    o.params = spec.params;
    o.remaps = spec.remaps;
    o.context = context;
    o.where = spec.where;
    try {
      nodes.push_back(registry.create(spec.pkg, spec.exec, o));
    } catch (const bus::ParamError& e) {
      throw LaunchError(e.where().known() ? e.where() : spec.where,
                        e.where().known() ? std::string(e.what()).substr(e.where().str().size() + 2) : e.what());
    } catch (const std::exception& e) {
      throw LaunchError(spec.where,
                        fmt::format("node '{}' ({}/{}) could not be built: {}", full, spec.pkg, spec.exec, e.what()));
    }
  }
  return nodes;
}

void configure(const LaunchPlan& plan, const std::vector<std::shared_ptr<bus::Node>>& nodes,
               const std::string& process) {
  std::size_t i = 0;
  for (const auto& spec : plan.nodes) {
    if (spec.process != process || i >= nodes.size()) continue;
    const auto& n = nodes[i++];
    try {
      n->on_configure();
    } catch (const bus::ParamError& e) {
      throw LaunchError(e.where().known() ? e.where() : spec.where,
                        e.where().known() ? std::string(e.what()).substr(e.where().str().size() + 2) : e.what());
    } catch (const std::exception& e) {
      throw LaunchError(
          spec.where, fmt::format("node '{}' ({}/{}) cannot start: {}", n->full_name(), spec.pkg, spec.exec, e.what()));
    }
  }
}

void check_files(const std::vector<std::shared_ptr<bus::Node>>& nodes) {
  std::map<std::string, FileUse> inputs, outputs;
  auto where = [](const FileUse& u) { return u.where.known() ? u.where.str() : "its default"; };
  for (const auto& n : nodes) {
    for (const auto& p : n->parameters()) {
      const auto* value = std::get_if<std::string>(&p.value);
      if (value == nullptr || !p.constraints.names_file(*value)) continue;
      const FileUse use{n->full_name(), p.name, p.set_from};
      const std::string key = file_key(*value);
      if (p.constraints.file == bus::ParamConstraints::File::Input) {
        inputs.emplace(key, use);
        continue;
      }
      auto [it, fresh] = outputs.emplace(key, use);
      if (!fresh) {
        throw LaunchError(use.where,
                          fmt::format("node '{}' writes '{}' ({}), which node '{}' writes too (its {} at {})", use.node,
                                      *value, use.param, it->second.node, it->second.param, where(it->second)));
      }
    }
  }
  for (const auto& [key, out] : outputs) {
    auto in = inputs.find(key);
    if (in == inputs.end()) continue;
    throw LaunchError(
        out.where, fmt::format("node '{}' would write '{}' ({}), which node '{}' reads (its {} at {})", out.node, key,
                               out.param, in->second.node, in->second.param, where(in->second)));
  }
}

}  // namespace tinyline::launch
