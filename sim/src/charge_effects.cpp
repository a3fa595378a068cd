// SPDX-License-Identifier: Apache-2.0
// The `charge` effect (effects.hpp): undeclared physics that acts on the two
// capacitors' charges rather than on the timing, its YAML and its application.
#include <algorithm>
#include <ostream>

#include <sim/effects.hpp>
#include <sim/yaml_node.hpp>

namespace tinyline::sim {

bool PixelGroup::contains(int pixel) const {
  if (!pixels.empty() && std::find(pixels.begin(), pixels.end(), pixel) == pixels.end()) return false;
  if (first >= 0 && last >= 0 && (pixel < first || pixel > last)) return false;
  if (parity >= 0 && pixel % 2 != parity) return false;
  return true;
}

void apply_charge_effects(const std::vector<const ChargeEffect*>& effects, int pixel, int pulses,
                          const std::map<std::string, double>& covariates, double& a, double& b) {
  using K = ChargeEffect::Kind;
  using C = ChargeEffect::Capacitor;
  for (const ChargeEffect* e : effects) {
    if (!e->pixels.contains(pixel)) continue;
    const bool on_a = e->capacitor != C::kB, on_b = e->capacitor != C::kA;
    if (e->kind == K::kGain) {
      if (on_a) a *= e->gain;
      if (on_b) b *= e->gain;
      continue;
    }
    double q = e->per_pulse * pulses;
    if (e->kind == K::kAmbient) {
      const auto it = covariates.find(e->covariate);
      q *= it == covariates.end() ? 0.0 : it->second;
    }
    if (on_a) a += q;
    if (on_b) b += q;
  }
}

namespace detail {

// Reads a `charge` effect (sensor YAML `effects:` item).
ChargeEffect read_charge_effect(const YamlNode& n) {
  n.check_keys({"type", "kind", "capacitor", "per_pulse", "gain", "covariate", "pixels", "range", "parity"});
  ChargeEffect e;
  const std::string kind = n.get_string("kind");
  if (kind == "ambient") {
    e.kind = ChargeEffect::Kind::kAmbient;
    e.capacitor = ChargeEffect::Capacitor::kBoth;
  } else if (kind == "leakage") {
    e.kind = ChargeEffect::Kind::kLeakage;
  } else if (kind == "gain") {
    e.kind = ChargeEffect::Kind::kGain;
  } else {
    n.at("kind").fail("'" + kind + "' is not ambient, leakage or gain");
  }
  const std::string cap = n.get_string("capacitor", e.capacitor == ChargeEffect::Capacitor::kBoth ? "both" : "b");
  if (cap == "a") {
    e.capacitor = ChargeEffect::Capacitor::kA;
  } else if (cap == "b") {
    e.capacitor = ChargeEffect::Capacitor::kB;
  } else if (cap == "both") {
    e.capacitor = ChargeEffect::Capacitor::kBoth;
  } else {
    n.at("capacitor").fail("'" + cap + "' is not a, b or both");
  }
  e.per_pulse = n.in_range("per_pulse", e.per_pulse, -10.0, 10.0);
  e.gain = n.in_range("gain", e.gain, 0.1, 10.0);
  e.covariate = n.get_string("covariate", "");
  if (e.kind == ChargeEffect::Kind::kAmbient && e.covariate.empty())
    n.fail("an ambient charge effect needs `covariate`");
  if (auto p = n.find("pixels")) {
    for (const auto& item : p->items()) e.pixels.pixels.push_back(item.as_int());
  }
  if (auto r = n.find("range")) {
    const auto v = r->as_doubles(2);
    e.pixels.first = static_cast<int>(v[0]);
    e.pixels.last = static_cast<int>(v[1]);
    if (e.pixels.first < 0 || e.pixels.last < e.pixels.first) r->fail("expected [first, last] with 0 <= first <= last");
  }
  if (auto p = n.find("parity")) {
    const std::string s = p->as_string();
    if (s != "even" && s != "odd") p->fail("'" + s + "' is not even or odd");
    e.pixels.parity = s == "odd" ? 1 : 0;
  }
  return e;
}

void write_charge_effect(std::ostream& s, const ChargeEffect& e) {
  const char* kinds[] = {"ambient", "leakage", "gain"};
  const char* caps[] = {"a", "b", "both"};
  s << "    kind: " << kinds[static_cast<int>(e.kind)] << "\n    capacitor: " << caps[static_cast<int>(e.capacitor)]
    << "\n    per_pulse: " << e.per_pulse << "\n    gain: " << e.gain << "\n";
  if (!e.covariate.empty()) s << "    covariate: " << e.covariate << "\n";
  if (!e.pixels.pixels.empty()) {
    s << "    pixels: [";
    for (std::size_t i = 0; i < e.pixels.pixels.size(); ++i) s << (i ? ", " : "") << e.pixels.pixels[i];
    s << "]\n";
  }
  if (e.pixels.first >= 0) s << "    range: [" << e.pixels.first << ", " << e.pixels.last << "]\n";
  if (e.pixels.parity >= 0) s << "    parity: " << (e.pixels.parity ? "odd" : "even") << "\n";
}

}  // namespace detail

}  // namespace tinyline::sim
