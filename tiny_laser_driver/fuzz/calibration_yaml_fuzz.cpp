// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: arbitrary bytes as a calibration YAML (what users edit by
// hand and `tinyline calib fit` writes). Properties beyond "no crash, no
// sanitizer report, no hang, bounded memory":
//  - a file is either loaded or refused with a std::runtime_error that names it;
//  - a loaded model writes YAML that loads again and writes the same text;
//  - a loaded model's polynomial reads near the physical range on its fitted range;
//  - no pixel the driver's scan processing calls valid lies outside 0-6 m
//    (Eq. 3.4), over read-outs that sweep the charge ratio and temperature.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include <tiny_laser_driver/calibration.hpp>
#include <tiny_laser_driver/calibration_impl.hpp>
#include <tiny_laser_driver/scan_processor.hpp>

namespace tl = tinyline::tiny_laser_driver;

namespace {

[[noreturn]] void violated(const char* what) {
  std::fprintf(stderr, "property violated: %s\n", what);
  std::abort();
}
void check(bool ok, const char* what) {
  if (!ok) violated(what);
}

// Five read-outs per pixel as the sensor sends them; pixel p sees charge
// ratio b / (a + b) sweeping 0..1 across the line, at one temperature.
tl::RawSet sweep(double light, std::uint16_t temperature_decic) {
  static constexpr std::uint16_t kPulses[5] = {20, 100, 200, 400, 700};
  tl::RawSet s;
  for (int i = 0; i < 5; ++i) {
    tl::RawFrame f;
    f.index = static_cast<std::uint16_t>(i);
    f.last = i == 4;
    f.pulses = kPulses[i];
    f.temperature_decic = temperature_decic;
    for (std::size_t p = 0; p < tl::kPixels; ++p) {
      const double k = static_cast<double>(p) / (tl::kPixels - 1);
      const double sum = light * kPulses[i];
      f.a[p] = static_cast<std::int16_t>(std::lround(10.0 * sum * (1.0 - k)));
      f.b[p] = static_cast<std::int16_t>(std::lround(10.0 * sum * k));
    }
    s.frames.push_back(f);
  }
  return s;
}

void check_published_values(const tl::CalibrationModel& model) {
  const tl::ScanProcessor proc(model, tl::OpticsParams{});
  tl::ProcessedScan out;
  for (const double light : {0.05, 0.3}) {
    for (const std::uint16_t t : {0, 480, 1250}) {
      proc.process(sweep(light, t), 12.0, out);
      for (std::size_t p = 0; p < tl::kPixels; ++p) {
        if (out.status[p] != tl::PixelStatus::kValid) continue;
        check(std::isfinite(out.distance_m[p]), "a valid pixel's distance is not finite");
        check(out.distance_m[p] >= tl::kPhysicalMinDistanceM && out.distance_m[p] <= tl::kPhysicalMaxDistanceM,
              "a valid pixel's distance is outside the physical range");
      }
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  tl::CalibrationModel model;
  try {
    model = tl::CalibrationModel::from_yaml(text, "fuzz.yaml");
  } catch (const std::runtime_error& e) {
    check(std::string(e.what()).rfind("fuzz.yaml", 0) == 0, "an error that does not name the file");
    return 0;
  }
  const auto& m = model.impl();
  check(!m.poly_m.empty() && m.poly_m.size() <= tl::kMaxPolynomialCoefficients, "a polynomial of a refused size");
  for (int i = 0; i <= 100; ++i) {
    const double d = m.polynomial_m(m.ratio_min + (m.ratio_max - m.ratio_min) * i / 100.0);
    check(std::isfinite(d) && std::abs(d) < 100.0, "a loaded polynomial reads absurdly on its fitted range");
  }
  const std::string written = model.to_yaml();
  try {
    const auto again = tl::CalibrationModel::from_yaml(written, "again.yaml");
    check(again.to_yaml() == written, "written, loaded and written again differs");
  } catch (const std::runtime_error& e) {
    std::fprintf(stderr, "%s\n", e.what());
    violated("a loaded model writes YAML that does not load");
  }
  check_published_values(model);
  return 0;
}
