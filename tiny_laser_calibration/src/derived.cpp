// SPDX-License-Identifier: Apache-2.0
// Covariates derived from the data set's own columns: the low-pass filtered
// temperature (a part that warms more slowly than the MCU's sensor).
#include <algorithm>
#include <cmath>
#include <numeric>

#include <fmt/format.h>

#include <tiny_laser_calibration/data.hpp>

namespace tinyline::tiny_laser_calibration {

namespace {
constexpr std::string_view kLagPrefix = "temperature_c_lp";
}

std::string lagged_temperature_name(double tau_s) { return fmt::format("{}{}s", kLagPrefix, std::lround(tau_s)); }

double lagged_temperature_tau(std::string_view name) {
  if (name.size() < kLagPrefix.size() + 2 || name.substr(0, kLagPrefix.size()) != kLagPrefix || name.back() != 's')
    return 0.0;
  double tau = 0.0;
  for (char c : name.substr(kLagPrefix.size(), name.size() - kLagPrefix.size() - 1)) {
    if (c < '0' || c > '9') return 0.0;
    tau = 10.0 * tau + (c - '0');
  }
  return tau;
}

CalibrationDataset with_lagged_temperature(const CalibrationDataset& data, const std::vector<double>& taus_s) {
  CalibrationDataset out = data;
  const auto frames = frame_ids(data);
  const int n_frames = frames.empty() ? 0 : *std::max_element(frames.begin(), frames.end()) + 1;
  // One temperature and time per frame; frames are numbered in (session, time) order.
  std::vector<double> t(static_cast<std::size_t>(n_frames), 0.0), temp(t.size(), 0.0), session(t.size(), 0.0);
  const int session_col = data.extra_index("session");
  for (std::size_t i = 0; i < data.size(); ++i) {
    const auto f = static_cast<std::size_t>(frames[i]);
    t[f] = data.readouts[i].t_s;
    temp[f] = data.readouts[i].temperature_c;
    session[f] = session_col >= 0 ? data.readouts[i].extra[static_cast<std::size_t>(session_col)] : 0.0;
  }
  for (double tau : taus_s) {
    const std::string name = lagged_temperature_name(tau);
    if (out.extra_index(name) >= 0 || !(tau > 0.0)) continue;
    std::vector<double> lp(t.size(), 0.0);
    for (std::size_t f = 0; f < t.size(); ++f) {
      const bool first = f == 0 || session[f] != session[f - 1];
      lp[f] = first ? temp[f] : lp[f - 1] + (1.0 - std::exp(-(t[f] - t[f - 1]) / tau)) * (temp[f] - lp[f - 1]);
    }
    out.extra_names.push_back(name);
    for (std::size_t i = 0; i < out.size(); ++i)
      out.readouts[i].extra.push_back(lp[static_cast<std::size_t>(frames[i])]);
  }
  return out;
}

CalibrationDataset with_derived_covariates(const CalibrationDataset& data, const std::vector<std::string>& names) {
  std::vector<double> taus;
  for (const auto& n : names) {
    if (data.extra_index(n) < 0 && lagged_temperature_tau(n) > 0.0) taus.push_back(lagged_temperature_tau(n));
  }
  return taus.empty() ? data : with_lagged_temperature(data, taus);
}

}  // namespace tinyline::tiny_laser_calibration
