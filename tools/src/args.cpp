#include "args.hpp"

#include <algorithm>

namespace tinyline::tools {

Args::Args(const std::vector<std::string>& argv, const std::vector<std::string>& valued,
           const std::vector<std::string>& flags) {
  for (std::size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    if (std::find(valued.begin(), valued.end(), a) != valued.end()) {
      if (i + 1 >= argv.size()) throw UsageError("option " + a + " needs a value");
      options_.emplace_back(a, argv[++i]);
    } else if (std::find(flags.begin(), flags.end(), a) != flags.end()) {
      flags_.push_back(a);
    } else if (a.size() > 1 && a[0] == '-' && a.find(":=") == std::string::npos) {
      throw UsageError("unknown option " + a);
    } else {
      positional_.push_back(a);
    }
  }
}

bool Args::flag(const std::string& name) const {
  return std::find(flags_.begin(), flags_.end(), name) != flags_.end();
}

std::optional<std::string> Args::value(const std::string& name) const {
  std::optional<std::string> v;
  for (const auto& [k, x] : options_)
    if (k == name) v = x;
  return v;
}

std::vector<std::string> Args::values(const std::string& name) const {
  std::vector<std::string> out;
  for (const auto& [k, x] : options_)
    if (k == name) out.push_back(x);
  return out;
}

double Args::number(const std::string& name, double fallback) const {
  auto v = value(name);
  if (!v) return fallback;
  try {
    std::size_t pos = 0;
    const double d = std::stod(*v, &pos);
    if (pos != v->size()) throw std::invalid_argument("");
    return d;
  } catch (const std::exception&) {
    throw UsageError("option " + name + " needs a number, got '" + *v + "'");
  }
}

std::pair<std::string, std::string> split_assignment(const std::string& s) {
  const auto at = s.find(":=");
  if (at == std::string::npos || at == 0) throw UsageError("expected name:=value, got '" + s + "'");
  return {s.substr(0, at), s.substr(at + 2)};
}

}  // namespace tinyline::tools
