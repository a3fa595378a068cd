// SPDX-License-Identifier: Apache-2.0
// The read-out noise law of section 3.5 from a calibration rail: how the
// spread of the charge ratio falls with the light of the read-out.
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include <tiny_laser_calibration/fit.hpp>
#include <tiny_laser_driver/protocol.hpp>

namespace tinyline::tiny_laser_calibration {

namespace {

using tiny_laser_driver::kPixels;

struct RatioError {
  double sum = 0.0;     // a + b of the read-out
  double pulses = 0.0;  // of the read-out
  double error = 0.0;
};

// Per driver read-out the error of its distance in units of X (the error over
// dL/dX), keyed by target distance and pixel: the sets that saw one target
// with one pixel, whose spread is the noise.
std::map<long, std::vector<RatioError>> ratio_errors(const CalibrationModel& model, const CalibrationDataset& data) {
  const auto& m = model.impl();
  const auto groups = target_distance_groups(data);
  const auto rows = select_readouts(data, {}, m.validity, ReadoutSelection::kDriver);
  std::map<long, std::vector<RatioError>> out;
  for (std::size_t i : rows) {
    const auto& r = data.readouts[i];
    const auto ev = model.evaluate(r);
    if (ev.status != CalibrationEvaluation::Status::kValid) continue;
    const double slope = m.polynomial_slope_m(ev.ratio);
    if (!(std::abs(slope) > 1e-9)) continue;
    const long key = static_cast<long>(groups[i]) * static_cast<long>(kPixels) + r.pixel;
    out[key].push_back({r.a + r.b, static_cast<double>(r.pulses), (ev.distance_m - data.distance_m[i]) / slope});
  }
  return out;
}

// Each error's squared deviation from its own target's and pixel's mean, scaled
// so its expectation is the variance (n / (n - 1)): the model's bias at that
// distance and pixel is not noise.
std::vector<RatioError> squared_deviations(const std::map<long, std::vector<RatioError>>& errors) {
  std::vector<RatioError> out;
  for (const auto& [key, es] : errors) {
    if (es.size() < 2) continue;
    double mean = 0.0;
    for (const auto& e : es) mean += e.error / static_cast<double>(es.size());
    const double scale = static_cast<double>(es.size()) / static_cast<double>(es.size() - 1);
    for (const auto& e : es) out.push_back({e.sum, e.pulses, scale * (e.error - mean) * (e.error - mean)});
  }
  return out;
}

// Least squares of var(X) S^2 = shot S + per_pulse p + read over the terms in
// `use`, each point weighted by its expected size squared (a squared deviation's
// spread grows with its mean): a few reweighting passes.
Eigen::Vector3d weighted_fit(const std::vector<RatioError>& dev, const std::array<bool, 3>& use) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  std::vector<double> w(dev.size(), 1.0);
  for (int pass = 0; pass < 4; ++pass) {
    Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
    Eigen::Vector3d aty = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < dev.size(); ++i) {
      const Eigen::Vector3d x(use[0] ? dev[i].sum : 0.0, use[1] ? dev[i].pulses : 0.0, use[2] ? 1.0 : 0.0);
      ata += w[i] * x * x.transpose();
      aty += w[i] * x * (dev[i].error * dev[i].sum * dev[i].sum);
    }
    for (int k = 0; k < 3; ++k) {
      if (!use[static_cast<std::size_t>(k)]) ata(k, k) = 1.0;  // the term held at 0
    }
    c = ata.ldlt().solve(aty);
    for (std::size_t i = 0; i < dev.size(); ++i) {
      const double pred = c[0] * dev[i].sum + c[1] * dev[i].pulses + c[2];
      w[i] = pred > 0.0 ? 1.0 / (pred * pred) : w[i];
    }
  }
  return c;
}

}  // namespace

tiny_laser_driver::NoiseLaw fit_noise_law(const CalibrationModel& model, const CalibrationDataset& data) {
  constexpr std::size_t kMinPoints = 200;
  const auto dev = squared_deviations(ratio_errors(model, data));
  if (dev.size() < kMinPoints) return {};
  // Variances cannot be negative: a term that comes out below 0 is dropped and the rest refitted.
  std::array<bool, 3> use{true, true, true};
  Eigen::Vector3d c = weighted_fit(dev, use);
  while (c.minCoeff() < 0.0) {
    Eigen::Index k = 0;
    c.minCoeff(&k);
    use[static_cast<std::size_t>(k)] = false;
    if (!use[0] && !use[1] && !use[2]) return {};
    c = weighted_fit(dev, use);
  }
  tiny_laser_driver::NoiseLaw law;
  law.shot = c[0];
  law.per_pulse = c[1];
  law.read = c[2];
  return law;
}

}  // namespace tinyline::tiny_laser_calibration
