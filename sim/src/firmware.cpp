#include <sim/firmware.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <tiny_laser_calibration/data.hpp>
#include <tiny_laser_calibration/fit.hpp>

#include <sim/fidelity.hpp>
#include <sim/rail.hpp>

namespace tinyline::sim {

namespace tld = tiny_laser_driver;
namespace cal = tiny_laser_calibration;

tld::CalibrationModel factory_calibration(const SensorParams& params) {
  // A white-paper sweep without noise, across the line and through the
  // warm-up, read out with the firmware's own accumulation buffer: the data
  // a factory would take, in the form the firmware will see.
  CalibrationRail rail(params);
  MeasureOptions clean;
  clean.noise = false;
  cal::CalibrationDataset data;
  data.source = "factory sweep";
  const int n = rail.sensor().pixels(), dark = params.lens.dark_pixels;
  std::vector<int> pixels;
  for (int i = dark + 4; i < n - dark - 4; i += 16) pixels.push_back(i);
  std::uint64_t index = 0;
  double t_row = 0.0;
  for (double t : {60.0, 240.0, 3600.0}) {
    for (double d = 0.05; d <= 3.0 + 1e-9; d += 0.05) {
      rail.set_target_distance(d);
      const SensorSet s = rail.measure(t, params.acquisition.distance_pulses, index++, clean);
      t_row += 1.0;
      for (int px : pixels) {
        const auto i = static_cast<std::size_t>(px);
        if (std::isnan(s.truth[i].range_m)) continue;
        for (const auto& ro : s.readouts) {
          tld::Readout r;
          r.a = ro.a[i];
          r.b = ro.b[i];
          r.pulses = ro.pulses;
          r.temperature_c = s.true_temperature_c;
          r.pixel = px;
          r.t_s = t_row;  // one frame: the fit keeps the read-out the firmware would
          data.add(r, s.truth[i].range_m);
        }
      }
    }
  }
  cal::DeclaredFitParams fp;
  fp.degree = 6;
  fp.sensitivity_ratio_mode = cal::SensitivityRatioMode::kFixed;  // the public driver's k = b / (a + b)
  fp.sensitivity_ratio = 1.0;
  fp.fit_leakage = true;
  fp.fit_temperature = true;
  fp.temperature_reference_c = params.thermal.warm_c;
  fp.selection = cal::ReadoutSelection::kDriver;
  const cal::DeclaredFitResult fit = cal::fit_declared_model(data, fp);
  if (!fit.ok) throw std::runtime_error("factory calibration failed: " + fit.reason);
  return fit.model;
}

std::vector<std::int16_t> firmware_distances_mm(const SensorSet& set, const tld::CalibrationModel& model) {
  const std::size_t n = set.readouts.empty() ? 0 : set.readouts.front().a.size();
  std::vector<std::int16_t> out(n, 0);
  const std::size_t dark = tld::kDarkPixels;
  for (std::size_t i = dark; i + dark < n; ++i) {  // dark pixels carry no range
    const int k = select_readout(set, static_cast<int>(i));
    if (k < 0) continue;
    const auto& ro = set.readouts[static_cast<std::size_t>(k)];
    tld::Readout r;
    r.a = ro.a[i];
    r.b = ro.b[i];
    r.pulses = ro.pulses;
    r.temperature_c = set.temperature_c;
    r.pixel = static_cast<int>(i);
    r.t_s = ro.t_s;
    const double mm = 1000.0 * model.distance_m(r);
    if (std::isfinite(mm) && mm >= 1.0 && mm <= 32767.0) out[i] = static_cast<std::int16_t>(std::lround(mm));
  }
  return out;
}

std::vector<tld::RawFrame> raw_frames(const SensorSet& set) {
  std::vector<tld::RawFrame> frames;
  const double t = std::clamp(set.temperature_c, 0.0, 65.4);
  for (std::size_t k = 0; k < set.readouts.size(); ++k) {
    const auto& ro = set.readouts[k];
    tld::RawFrame f;
    f.index = static_cast<std::uint16_t>(k);
    f.last = (k + 1 == set.readouts.size());
    f.temperature_decic = static_cast<std::uint16_t>(std::lround(t * 10.0));
    f.pulses = static_cast<std::uint16_t>(ro.pulses);
    const std::size_t n = std::min<std::size_t>(ro.a.size(), tld::kPixels);
    for (std::size_t i = 0; i < n; ++i) {
      f.a[i] = static_cast<std::int16_t>(std::clamp(std::lround(ro.a[i] * 10.0), -32768L, 32767L));
      f.b[i] = static_cast<std::int16_t>(std::clamp(std::lround(ro.b[i] * 10.0), -32768L, 32767L));
    }
    frames.push_back(f);
  }
  return frames;
}

}  // namespace tinyline::sim
