#include <tinyline/launch/launch.hpp>

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include <fmt/format.h>

#include <tinyline/bus/detail/yaml_params.hpp>

namespace tinyline::launch {

namespace fs = std::filesystem;
using bus::SourceLocation;

namespace {

// The YAML typing rules of parameters live in the bus (shared with -p name:=value).
std::optional<bus::ParamValue> scalar_or_list(const YAML::Node& n, std::string* why) {
  return bus::param_from_yaml(n, why);
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

  SourceLocation loc(const Scope& s, const YAML::Node& n) const {
    const YAML::Mark m = n.Mark();
    return SourceLocation{s.file, m.line >= 0 ? m.line + 1 : 0, m.column >= 0 ? m.column + 1 : 0};
  }

  [[noreturn]] void fail(const Scope& s, const YAML::Node& n, const std::string& what) const {
    throw LaunchError(loc(s, n), what);
  }

  void check_keys(const Scope& s, const YAML::Node& map, const std::vector<std::string>& allowed,
                  const std::string& what) const {
    if (!map.IsMap()) fail(s, map, what + " must be a mapping");
    for (const auto& kv : map) {
      const std::string key = kv.first.Scalar();
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        fail(s, kv.first, fmt::format("unknown key '{}' in {} (allowed: {})", key, what, list));
      }
    }
  }

  std::string substitute(const Scope& s, const YAML::Node& n, const std::string& text) const {
    std::string out;
    std::size_t i = 0;
    while (i < text.size()) {
      if (text.compare(i, 2, "$(") != 0) {
        out += text[i++];
        continue;
      }
      // Find the matching ')', allowing nested substitutions.
      int depth = 0;
      std::size_t j = i;
      for (; j < text.size(); ++j) {
        if (text.compare(j, 2, "$(") == 0) {
          ++depth;
          ++j;
        } else if (text[j] == ')') {
          if (--depth == 0) break;
        }
      }
      if (j >= text.size()) fail(s, n, "unterminated substitution in '" + text + "'");
      const std::string inner = substitute(s, n, text.substr(i + 2, j - i - 2));
      std::istringstream words(inner);
      std::string cmd;
      words >> cmd;
      std::vector<std::string> argv;
      for (std::string w; words >> w;) argv.push_back(w);
      if (cmd == "var") {
        if (argv.size() != 1) fail(s, n, "$(var) takes one name");
        auto it = s.vars.find(argv[0]);
        if (it == s.vars.end()) {
          std::string known;
          for (const auto& [k, v] : s.vars) known += (known.empty() ? "" : ", ") + k;
          fail(s, n, fmt::format("unknown launch argument '{}' in $(var {}) (known: {})", argv[0], argv[0],
                                 known.empty() ? "none" : known));
        }
        out += it->second;
      } else if (cmd == "env") {
        if (argv.empty() || argv.size() > 2) fail(s, n, "$(env NAME [default]) takes one or two words");
        const char* v = std::getenv(argv[0].c_str());
        if (v != nullptr) {
          out += v;
        } else if (argv.size() == 2) {
          out += argv[1];
        } else {
          fail(s, n, fmt::format("environment variable '{}' is not set (give a default: $(env {} value))", argv[0],
                                 argv[0]));
        }
      } else if (cmd == "dirname") {
        out += s.dir;
      } else if (cmd == "find-pkg-share") {
        if (argv.size() != 1) fail(s, n, "$(find-pkg-share) takes one package name");
        if (options.share_dir.empty()) fail(s, n, "$(find-pkg-share) is not available: no share directory configured");
        out += options.share_dir;
      } else {
        fail(s, n, fmt::format("unknown substitution '$({})' (known: var, env, dirname, find-pkg-share)", cmd));
      }
      i = j + 1;
    }
    return out;
  }

  std::string str(const Scope& s, const YAML::Node& n, const std::string& what) const {
    if (!n.IsScalar()) fail(s, n, what + " must be a scalar");
    return substitute(s, n, n.Scalar());
  }

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

  void load_file(const std::string& path, std::map<std::string, std::string> given, const Scope& outer,
                 const SourceLocation& from) {
    std::error_code ec;
    const std::string abs = fs::weakly_canonical(fs::path(path), ec).string();
    if (std::find(stack.begin(), stack.end(), abs) != stack.end()) {
      std::string chain;
      for (const auto& f : stack) chain += display(f) + " -> ";
      throw LaunchError(from, "include cycle: " + chain + display(abs));
    }
    std::ifstream in(path);
    if (!in) throw LaunchError(from, "cannot open launch file '" + path + "'");
    std::stringstream text;
    text << in.rdbuf();
    stack.push_back(abs);
    Scope s;
    s.file = path;
    s.dir = fs::path(abs).parent_path().string();
    s.ns = outer.ns;
    s.process = outer.process;
    s.dds = outer.dds;
    load_text(text.str(), s, std::move(given), stack.size() == 1);
    stack.pop_back();
  }

  void load_text(const std::string& text, Scope& s, std::map<std::string, std::string> given, bool top) {
    plan.files.push_back(s.file);
    YAML::Node root;
    try {
      root = YAML::Load(text);
    } catch (const YAML::Exception& e) {
      throw LaunchError(SourceLocation{s.file, e.mark.line + 1, e.mark.column + 1},
                        "YAML syntax error: " + e.msg);
    }
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
        check_keys(s, v, {"name", "value"}, "let");
        if (!v["name"] || !v["value"]) fail(s, v, "let needs name and value");
        s.vars[str(s, v["name"], "let name")] = str(s, v["value"], "let value");
      } else if (kind == "include") {
        action_include(s, v);
      } else if (kind == "group") {
        action_group(s, v, given, declared);
      } else if (kind == "push-ros-namespace" || kind == "push_ros_namespace") {
        check_keys(s, v, {"namespace"}, kind);
        if (!v["namespace"]) fail(s, v, kind + " needs a namespace");
        const std::string ns = str(s, v["namespace"], "namespace");
        try {
          s.ns = bus::join_namespace(s.ns, ns);
          if (s.ns != "/") bus::validate_name(s.ns, "namespace");
        } catch (const std::invalid_argument& e) {
          fail(s, v["namespace"], e.what());
        }
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
      fail(s, v, fmt::format("missing required launch argument '{}'{} (pass {}:=VALUE)", a.name,
                             a.description.empty() ? "" : " (" + a.description + ")", a.name));
    }
    if (top) plan.args.push_back(a);
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

  void action_node(const Scope& s, const YAML::Node& v) {
    check_keys(s, v, {"pkg", "exec", "name", "namespace", "param", "remap", "respawn", "output", "process", "dds"},
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
    try {
      n.ns = v["namespace"] ? bus::join_namespace(s.ns, str(s, v["namespace"], "namespace")) : s.ns;
      if (n.ns != "/") bus::validate_name(n.ns, "namespace");
    } catch (const std::invalid_argument& e) {
      fail(s, v["namespace"], e.what());
    }
    if (v["respawn"]) n.respawn = boolean(s, v["respawn"], "respawn");
    n.dds = v["dds"] ? boolean(s, v["dds"], "dds") : s.dds;
    if (v["output"]) {
      const std::string o = str(s, v["output"], "output");
      if (o != "screen" && o != "log") fail(s, v["output"], "output must be screen or log");
    }
    const std::string full = (n.ns == "/" ? "" : n.ns) + "/" + n.name;
    if (v["param"]) {
      if (!v["param"].IsSequence()) fail(s, v["param"], "param must be a list of {name, value} or {from: file}");
      for (const auto& p : v["param"]) {
        if (p.IsMap() && p["from"]) {
          check_keys(s, p, {"from"}, "param");
          const std::string path = resolve_path(s, str(s, p["from"], "from"));
          try {
            auto from_file = load_param_file(path, full);
            n.params.insert(n.params.end(), from_file.begin(), from_file.end());
          } catch (const LaunchError& e) {
            throw;
          } catch (const std::exception& e) {
            fail(s, p["from"], e.what());
          }
          continue;
        }
        check_keys(s, p, {"name", "value"}, "param");
        if (!p["name"] || !p["value"]) fail(s, p, "param needs name and value");
        n.params.push_back(bus::ParamOverride{str(s, p["name"], "param name"), param_value(s, p["value"]),
                                              loc(s, p["value"])});
      }
    }
    if (v["remap"]) {
      if (!v["remap"].IsSequence()) fail(s, v["remap"], "remap must be a list of {from, to}");
      for (const auto& r : v["remap"]) {
        check_keys(s, r, {"from", "to"}, "remap");
        if (!r["from"] || !r["to"]) fail(s, r, "remap needs from and to");
        bus::Remap rm{str(s, r["from"], "from"), str(s, r["to"], "to")};
        try {
          bus::validate_name(rm.from, "remap source");
          bus::validate_name(rm.to, "remap target");
        } catch (const std::invalid_argument& e) {
          fail(s, r, e.what());
        }
        n.remaps.push_back(rm);
      }
    }
    plan.nodes.push_back(std::move(n));
  }

  bool boolean(const Scope& s, const YAML::Node& n, const std::string& what) const {
    const std::string b = str(s, n, what);
    if (b != "true" && b != "false") fail(s, n, what + " must be true or false");
    return b == "true";
  }

  void action_dds(const Scope& s, const YAML::Node& v) {
    check_keys(s, v, {"topics", "domain_id", "config"}, "dds");
    DdsPlan& d = plan.dds;
    if (!d.where.known()) d.where = loc(s, v);
    if (const YAML::Node t = v["topics"]) {
      if (t.IsScalar()) {
        if (str(s, t, "topics") != "all") fail(s, t, "dds topics must be 'all' or a list of absolute topic names");
        d.all = true;
      } else if (t.IsSequence()) {
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
      } else {
        fail(s, t, "dds topics must be 'all' or a list of absolute topic names");
      }
    }
    if (const YAML::Node id = v["domain_id"]) {
      const std::string text = str(s, id, "domain_id");
      char* end = nullptr;
      const long n = std::strtol(text.c_str(), &end, 10);
      if (text.empty() || *end != '\0' || n < 0 || n > 232) {
        fail(s, id, "dds domain_id must be an integer in 0..232, got '" + text + "'");
      }
      if (d.domain_id && *d.domain_id != n) {
        fail(s, id, fmt::format("dds domain_id {} contradicts domain_id {} given at {}", n, *d.domain_id,
                                d.where.str()));
      }
      d.domain_id = static_cast<int>(n);
    }
    if (const YAML::Node c = v["config"]) {
      std::string cfg = str(s, c, "config");
      // XML text and file:// URIs pass as they are (CYCLONEDDS_URI syntax);
      // a plain path is relative to this launch file and must exist.
      if (!cfg.empty() && cfg[0] != '<' && cfg.rfind("file://", 0) != 0) {
        fs::path p(cfg);
        if (p.is_relative()) p = fs::path(s.dir) / p;
        std::error_code ec;
        if (!fs::exists(p, ec)) fail(s, c, "dds config file '" + p.lexically_normal().string() + "' does not exist");
        cfg = "file://" + fs::absolute(p, ec).lexically_normal().string();
      }
      d.config = cfg;
    }
  }

  bus::ParamValue param_value(const Scope& s, const YAML::Node& n) const {
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
      if (auto v = scalar_or_list(copy, &why)) return *v;
      fail(s, n, "bad parameter value: " + why);
    }
    if (auto v = scalar_or_list(n, &why)) return *v;
    fail(s, n, "bad parameter value: " + why);
  }
};

}  // namespace

namespace {
void flatten(const YAML::Node& n, const std::string& prefix, const std::string& file,
             std::vector<bus::ParamOverride>& out) {
  for (const auto& kv : n) {
    const std::string key = prefix.empty() ? kv.first.Scalar() : prefix + "." + kv.first.Scalar();
    if (kv.second.IsMap()) {
      flatten(kv.second, key, file, out);
      continue;
    }
    std::string why;
    const YAML::Mark m = kv.second.Mark();
    const SourceLocation where{file, m.line + 1, m.column + 1};
    auto v = bus::param_from_yaml(kv.second, &why);
    if (!v) throw LaunchError(where, "bad parameter value for '" + key + "': " + why);
    out.push_back(bus::ParamOverride{key, *v, where});
  }
}
}  // namespace

std::vector<bus::ParamOverride> load_param_file(const std::string& path, const std::string& node_full_name) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw LaunchError(SourceLocation{path, 0, 0}, "cannot open parameter file");
  } catch (const YAML::Exception& e) {
    throw LaunchError(SourceLocation{path, e.mark.line + 1, e.mark.column + 1}, "YAML syntax error: " + e.msg);
  }
  if (!root.IsMap()) throw LaunchError(SourceLocation{path, 1, 1}, "a parameter file maps node names to ros__parameters");
  const std::string short_name = node_full_name.substr(node_full_name.rfind('/') + 1);
  std::vector<bus::ParamOverride> out;
  // Wildcard first so a node-specific entry wins (the last override wins).
  for (const char* pass : {"wild", "exact"}) {
    for (const auto& kv : root) {
      const std::string key = kv.first.Scalar();
      const bool wild = key == "/**";
      const bool exact = key == node_full_name || key == short_name || key == node_full_name.substr(1);
      if ((std::string(pass) == "wild" && !wild) || (std::string(pass) == "exact" && !exact)) continue;
      const YAML::Node params = kv.second["ros__parameters"];
      if (!params || !params.IsMap()) {
        const YAML::Mark m = kv.second.Mark();
        throw LaunchError(SourceLocation{path, m.line + 1, m.column + 1},
                          "entry '" + key + "' needs a 'ros__parameters' mapping");
      }
      flatten(params, "", path, out);
    }
  }
  return out;
}

LaunchPlan load_launch_file(const std::string& path, const LoadOptions& options) {
  Loader l{options, {}, {}};
  Scope outer;
  l.load_file(path, options.args, outer, SourceLocation{path, 0, 0});
  return std::move(l.plan);
}

LaunchPlan load_launch_string(const std::string& yaml, const std::string& source_name, const LoadOptions& options) {
  Loader l{options, {}, {}};
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
      throw LaunchError(spec.exec_where.known() ? spec.exec_where : spec.where,
                        fmt::format("unknown node type '{}/{}' (known: {})", spec.pkg, spec.exec,
                                    known.empty() ? "none" : known));
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
      throw LaunchError(spec.where, fmt::format("node '{}' ({}/{}) could not be built: {}", full, spec.pkg,
                                                spec.exec, e.what()));
    }
  }
  return nodes;
}

}  // namespace tinyline::launch
