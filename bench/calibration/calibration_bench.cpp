// SPDX-License-Identifier: Apache-2.0
// Cost of calibration at run time and at fit time, each beside a reference in
// the same run:
//   per raw set (256 pixels): CalibrationModel::distance_m vs the public
//   driver's formula (k = b / (a + b), a degree-6 polynomial, temperature);
//   fitting: fit_declared_model vs one QR polynomial fit of the same rows.
#include <benchmark/benchmark.h>

#include <Eigen/Dense>

#include <tiny_laser_calibration/discovery.hpp>

#include "synthetic_sensor.hpp"

namespace tl = tinyline::tiny_laser_driver;
namespace cal = tinyline::tiny_laser_calibration;
namespace tt = tinyline::tiny_laser_calibration::testing;

namespace {

struct Fixture {
  cal::CalibrationDataset data;
  tl::CalibrationModel declared;
  tl::CalibrationModel with_terms;
  std::vector<tl::Readout> frame;  // one read-out per pixel, 256 pixels
  std::vector<double> public_poly;

  Fixture() {
    auto plan = tt::default_rail();
    data = tt::simulate_rail({}, plan);
    declared = cal::fit_declared_model(data).model;
    with_terms = declared;
    // Two typical discovered terms: a smooth in albedo and a per-pixel table.
    tl::CalibrationTerm albedo;
    albedo.covariate = "albedo";
    albedo.knots = {0.1, 0.5, 0.7, 0.8, 0.9, 1.0, 1.2, 3.0};
    albedo.values = {0.09, 0.01, 0.008, 0.004, 0.002, 0.0, -0.01, -0.015};
    tl::CalibrationTerm pixel;
    pixel.covariate = "pixel";
    pixel.form = tl::TermForm::kTable;
    for (long px = 8; px < 264; ++px) {
      pixel.keys.push_back(px);
      pixel.offsets_m.push_back(1e-4 * static_cast<double>(px % 7));
    }
    with_terms.impl().terms = {albedo, pixel};
    with_terms.impl().resolve();
    // A frame: the driver's read-out of every ranging pixel at 0.8 m.
    for (std::size_t i = 0; i < data.size() && frame.size() < 256; ++i) {
      if (std::abs(data.distance_m[i] - 0.8) < 0.05 && data.readouts[i].pulses == 400)
        frame.push_back(data.readouts[i]);
    }
    while (frame.size() < 256) frame.push_back(frame[frame.size() % 64]);
    for (std::size_t i = 0; i < frame.size(); ++i) frame[i].pixel = static_cast<int>(8 + i);
    public_poly = {
        2.147918234375362e+06, -7.736068312640203e+06, 1.154494186428487e+07, -9.137795412258314e+06,
        4.045684724836031e+06, -9.494901699902674e+05, 9.219599710241470e+04};  // the public driver's sensor K
  }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

// The public driver: validity, k = b / (a + b), Horner in k, temperature offset (cm).
void BM_RawSet_Reference_PublicDriverPolynomial(benchmark::State& state) {
  const auto& f = fixture();
  for (auto _ : state) {
    double sum = 0.0;
    for (const auto& r : f.frame) {
      if (r.a > 10 && r.a < 230 && r.b > 10 && r.b < 230 && r.a + r.b > 10 + 0.4 * r.pulses / 10.0) {
        const double k = r.b / (r.a + r.b);
        double cm = 0.0;
        for (double c : f.public_poly) cm = cm * k + c;
        sum += cm + (440.0 - r.temperature_c * 10.0) * 0.05623;
      }
    }
    benchmark::DoNotOptimize(sum);
  }
  state.counters["pixels/s"] =
      benchmark::Counter(static_cast<double>(state.iterations() * f.frame.size()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_RawSet_Reference_PublicDriverPolynomial);

void BM_RawSet_DeclaredModel(benchmark::State& state) {
  const auto& f = fixture();
  for (auto _ : state) {
    double sum = 0.0;
    for (const auto& r : f.frame) sum += f.declared.distance_m(r);
    benchmark::DoNotOptimize(sum);
  }
  state.counters["pixels/s"] =
      benchmark::Counter(static_cast<double>(state.iterations() * f.frame.size()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_RawSet_DeclaredModel);

void BM_RawSet_ModelWithAlbedoAndPixelTerms(benchmark::State& state) {
  const auto& f = fixture();
  for (auto _ : state) {
    double sum = 0.0;
    for (const auto& r : f.frame) sum += f.with_terms.distance_m(r);
    benchmark::DoNotOptimize(sum);
  }
  state.counters["pixels/s"] =
      benchmark::Counter(static_cast<double>(state.iterations() * f.frame.size()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_RawSet_ModelWithAlbedoAndPixelTerms);

// Fitting: one QR of a degree-6 polynomial in b / (a + b) over the valid rows.
void BM_Fit_Reference_QrPolynomial(benchmark::State& state) {
  const auto& f = fixture();
  const auto rows = cal::select_readouts(f.data, {}, tl::ValidityRule{}, cal::ReadoutSelection::kDriver);
  for (auto _ : state) {
    Eigen::MatrixXd a(static_cast<Eigen::Index>(rows.size()), 7);
    Eigen::VectorXd y(static_cast<Eigen::Index>(rows.size()));
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const auto& r = f.data.readouts[rows[i]];
      const double k = r.b / (r.a + r.b) - 0.6;
      double p = 1.0;
      for (int c = 0; c < 7; ++c, p *= k) a(static_cast<Eigen::Index>(i), c) = p;
      y[static_cast<Eigen::Index>(i)] = f.data.distance_m[rows[i]];
    }
    Eigen::VectorXd c = a.colPivHouseholderQr().solve(y);
    benchmark::DoNotOptimize(c.data());
  }
  state.counters["rows"] = static_cast<double>(rows.size());
}
BENCHMARK(BM_Fit_Reference_QrPolynomial)->Unit(benchmark::kMillisecond);

void BM_Fit_DeclaredModel(benchmark::State& state) {
  const auto& f = fixture();
  std::size_t used = 0;
  for (auto _ : state) {
    const auto r = cal::fit_declared_model(f.data);
    used = r.used;
    benchmark::DoNotOptimize(r.rmse_m);
  }
  state.counters["rows"] = static_cast<double>(used);
}
BENCHMARK(BM_Fit_DeclaredModel)->Unit(benchmark::kMillisecond);

void BM_Fit_DiscoverEffects(benchmark::State& state) {
  const auto& f = fixture();
  for (auto _ : state) {
    const auto r = cal::discover_effects(f.data);
    benchmark::DoNotOptimize(r.rmse_after_m);
  }
  state.counters["rows"] = static_cast<double>(f.data.size());
}
BENCHMARK(BM_Fit_DiscoverEffects)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
