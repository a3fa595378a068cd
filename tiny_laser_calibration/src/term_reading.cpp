// SPDX-License-Identifier: Apache-2.0
// A discovered term in the units of its physics (discovery.hpp term_reading).
#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include <tiny_laser_calibration/discovery.hpp>
#include <tiny_laser_driver/protocol.hpp>

namespace tinyline::tiny_laser_calibration {

namespace {

constexpr double kLightMPerPs = 299792458.0e-12;  // c [m/ps]

std::string group_name(const CalibrationTerm& t, double id) {
  const int n = covariate_parameter(t.covariate);
  const auto k = covariate_from_name(t.covariate);
  if (k == Covariate::kPixelParity) return id > 0.5 ? "odd pixels" : "even pixels";
  if (k == Covariate::kPixelIs) return id > 0.5 ? fmt::format("pixel {}", n) : "the other pixels";
  if (k == Covariate::kPixelBank) {
    const int first = static_cast<int>(tiny_laser_driver::kDarkPixels) + static_cast<int>(id) * n;
    return fmt::format("pixels {}-{}", first, first + n - 1);
  }
  return fmt::format("{} = {}", t.covariate, id);
}

std::string what(TermForm f) {
  switch (f) {
    case TermForm::kChargeA: return "charge_unit added to capacitor A";
    case TermForm::kChargeB: return "charge_unit added to capacitor B";
    case TermForm::kChargeBoth: return "charge_unit added to both capacitors";
    case TermForm::kChargeAPerPulse: return "charge_unit per pulse added to capacitor A";
    case TermForm::kChargeBPerPulse: return "charge_unit per pulse added to capacitor B";
    case TermForm::kChargeBothPerPulse: return "charge_unit per pulse added to both capacitors";
    case TermForm::kGainA: return "relative gain of capacitor A";
    case TermForm::kGainB: return "relative gain of capacitor B";
    default: return "";
  }
}

std::string charge_reading(const CalibrationTerm& t) {
  const auto k = covariate_from_name(t.covariate);
  const bool gain = t.form == TermForm::kGainA || t.form == TermForm::kGainB;
  auto value = [&](double v) { return gain ? fmt::format("{:+.2f} %", 100.0 * v) : fmt::format("{:+.4g}", v); };
  if (t.form == TermForm::kReadout) {
    std::string s = "read-out of each capacitor corrected by";
    for (std::size_t i = 0; i < t.knots.size(); ++i) s += fmt::format(" {} at {:.0f}", value(t.values[i]), t.knots[i]);
    return s + " charge_unit";
  }
  if (k == Covariate::kOne) return fmt::format("{} {}", value(t.values.front()), what(t.form));
  if (k == Covariate::kPixelParity || k == Covariate::kPixelBank || k == Covariate::kPixelIs) {
    // The first group is the reference (held at 0), unless the term is centred (a charge
    // per pulse fitted on one surface): then every group, their mean held at 0.
    const bool centred = t.values.front() != 0.0;
    std::string s;
    for (std::size_t i = centred ? 0 : 1; i < t.knots.size(); ++i) {
      s += fmt::format("{}{} {}", s.empty() ? "" : "; ", value(t.values[i]), group_name(t, t.knots[i]));
    }
    if (centred) return fmt::format("{} ({}; their mean over the calibration's read-outs is 0)", s, what(t.form));
    return fmt::format("{} ({} relative to {})", s, what(t.form), group_name(t, t.knots.front()));
  }
  // A continuous covariate: the slope over its range, and the values at the ends.
  const double dz = t.knots.back() - t.knots.front();
  const double slope = dz > 0 ? (t.values.back() - t.values.front()) / dz : 0.0;
  return fmt::format("{} ({}) per unit of {}: {} at {:.4g}, {} at {:.4g}", value(slope), what(t.form), t.covariate,
                     value(t.values.front()), t.knots.front(), value(t.values.back()), t.knots.back());
}

}  // namespace

std::string term_reading(const CalibrationTerm& t) {
  if (acts_on_charges(t.form)) return charge_reading(t);
  if (t.form == TermForm::kTable) {
    const auto [lo, hi] = std::minmax_element(t.offsets_m.begin(), t.offsets_m.end());
    if (lo == t.offsets_m.end()) return "";
    return fmt::format("distance offsets {:+.2f} to {:+.2f} cm over {} values of {} (a delay of {:+.0f} to {:+.0f} ps)",
                       100.0 * *lo, 100.0 * *hi, t.keys.size(), t.covariate, 2.0 * *lo / kLightMPerPs,
                       2.0 * *hi / kLightMPerPs);
  }
  if (t.values.empty()) return "";
  const auto [lo, hi] = std::minmax_element(t.values.begin(), t.values.end());
  if (t.form == TermForm::kLightWalk) {
    std::string cs;
    for (std::size_t k = 0; k < t.values.size(); ++k)
      cs += fmt::format("{}{:+.3f} cm ln^{}", k ? " " : "", 100.0 * t.values[k], k + 1);
    return fmt::format("time walk {} of {} / {:.4g}, held on {:.4g}-{:.4g} ({:+.0f} ps per decade at the reference)",
                       cs, t.covariate, t.reference, t.knots.front(), t.knots.back(),
                       2.0 * t.values[0] * std::log(10.0) / kLightMPerPs);
  }
  if (t.form == TermForm::kAmplitudeInteraction) {
    return fmt::format("{:+.2f} to {:+.2f} cm per amplitude SD ({:.1f} charge_unit) over {}", 100.0 * *lo, 100.0 * *hi,
                       t.amplitude_scale, t.covariate);
  }
  // The term is fitted together with the polynomial in X: where the covariate
  // follows the distance the two trade off, and the term's own span can be far
  // larger than the change in any distance, which the held-out RMSE measures.
  return fmt::format(
      "the term's own offset spans {:+.2f} to {:+.2f} cm (a round-trip delay of {:+.0f} to {:+.0f} ps) over {} "
      "{:.4g}-{:.4g}; the polynomial, fitted with it, takes back the part that follows the distance, so this "
      "span is not a change of the distances: the held-out RMSE is",
      100.0 * *lo, 100.0 * *hi, 2.0 * *lo / kLightMPerPs, 2.0 * *hi / kLightMPerPs, t.covariate, t.knots.front(),
      t.knots.back());
}

}  // namespace tinyline::tiny_laser_calibration
