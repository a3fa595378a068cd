// SPDX-License-Identifier: Apache-2.0
#include <sim/tof_sensor.hpp>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <optional>
#include <stdexcept>

#include <tinyline/common/random.hpp>

namespace tinyline::sim {

namespace {

constexpr double kNsPerM = 1e9 / kSpeedOfLight;  // one-way light time per metre [ns]

double normal_cdf(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

double deg(double d) { return d * M_PI / 180.0; }

// Fan profile: flat inside, cos^2 taper over the soft edge.
double fan_weight(double phi_rad, const EmitterParams& e) {
  const double half = deg(e.fan_half_angle_deg), edge = deg(e.fan_edge_deg);
  const double a = std::abs(phi_rad);
  if (a <= half - 0.5 * edge) return 1.0;
  if (a >= half + 0.5 * edge) return 0.0;
  const double c = std::cos(0.5 * M_PI * (a - (half - 0.5 * edge)) / edge);
  return c * c;
}

// Soft saturation: linear up to the knee, then an exponential approach to full scale.
double compress(double v, double knee, double full) {
  if (v <= knee) return v;
  const double span = full - knee;
  if (span <= 0) return full;
  return knee + span * (1.0 - std::exp(-(v - knee) / span));
}

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

}  // namespace

struct TofLineSensor::Impl {
  int n = 0, s = 0, nsub = 0;
  std::vector<Eigen::Vector3d> sub_dir;  // sensor frame
  std::vector<double> sub_vign;
  std::vector<Eigen::Vector3d> px_dir;
  std::vector<double> px_angle;
  std::vector<char> dark;
  std::vector<double> rsen, leak, prnu, skew_ns;

  // Lens: core blur over sub-rays (FIR), halo over pixels (two-sided exponential IIR).
  int core_radius = 0;         // in sub-rays, each side
  std::vector<double> core_w;  // index o + core_radius, o = j - s*i
  double halo_h = 0.0, halo_a = 0.0;

  // Gate tables over the arrival delay Td [ns].
  double td0 = 0.0, dtd = 0.005;
  std::vector<double> fa, fb, dfa, dfb;

  // Effects, resolved.
  const TrapDelayEffect* trap = nullptr;
  const RangeWalkEffect* walk = nullptr;
  const MaterialBiasEffect* material_bias = nullptr;
  const TimeDriftEffect* time_drift = nullptr;
  const TemperatureLagEffect* temp_lag = nullptr;
  std::vector<const CovariateEffect*> covariates;
  std::vector<const ChargeEffect*> charge;
  bool need_derivative = false;

  // Random walks of covariates, extended on demand (1 s steps).
  mutable std::mutex walk_mu;
  mutable std::vector<std::vector<double>> walk_paths;

  double lookup(const std::vector<double>& t, double td) const {
    const double x = (td - td0) / dtd;
    if (!(x >= 0.0)) return 0.0;
    const auto i = static_cast<std::size_t>(x);
    if (i + 1 >= t.size()) return 0.0;
    const double f = x - static_cast<double>(i);
    return t[i] + f * (t[i + 1] - t[i]);
  }

  // Spreads sub-ray values onto pixels: (1-h) * core blur + h * halo.
  void blur(const std::vector<double>& in, std::vector<double>& out, std::vector<double>& binned) const {
    out.assign(static_cast<std::size_t>(n), 0.0);
    binned.assign(static_cast<std::size_t>(n), 0.0);
    for (int j = 0; j < nsub; ++j) binned[static_cast<std::size_t>(j / s)] += in[static_cast<std::size_t>(j)];
    for (int i = 0; i < n; ++i) {
      const int j0 = std::max(0, s * i - core_radius), j1 = std::min(nsub - 1, s * i + core_radius);
      double acc = 0.0;
      const double* w = core_w.data() + (j0 - s * i + core_radius);
      for (int j = j0; j <= j1; ++j) acc += *w++ * in[static_cast<std::size_t>(j)];
      out[static_cast<std::size_t>(i)] = (1.0 - halo_h) * acc;
    }
    if (halo_h > 0.0) {
      // y_i = sum_k x_k c a^|i-k|, c = (1-a)/(1+a) normalises the discrete kernel.
      const double a = halo_a, c = (1.0 - a) / (1.0 + a);
      double fwd = 0.0;
      std::vector<double> f(static_cast<std::size_t>(n));
      for (int i = 0; i < n; ++i) f[static_cast<std::size_t>(i)] = fwd = binned[static_cast<std::size_t>(i)] + a * fwd;
      double bwd = 0.0;
      for (int i = n - 1; i >= 0; --i) {
        bwd = binned[static_cast<std::size_t>(i)] + a * bwd;
        out[static_cast<std::size_t>(i)] +=
            halo_h * c * (f[static_cast<std::size_t>(i)] + bwd - binned[static_cast<std::size_t>(i)]);
      }
    }
  }

  double covariate_value(std::size_t k, double t_s, std::uint64_t seed) const {
    const CovariateEffect& c = *covariates[k];
    double v = c.mean + c.amplitude * std::sin(2.0 * M_PI * t_s / c.period_s);
    if (c.random_walk_per_sqrt_s > 0.0 && t_s > 0.0) {
      std::lock_guard<std::mutex> lock(walk_mu);
      auto& path = walk_paths[k];
      const auto need = static_cast<std::size_t>(t_s) + 2;
      if (path.empty()) path.push_back(0.0);
      if (path.size() < need) {
        common::XoshiroRandom rng(common::mix_seed(seed, 0xC0FFEEull + k, path.size()));
        while (path.size() < need) path.push_back(path.back() + c.random_walk_per_sqrt_s * rng.normal());
      }
      const auto i = static_cast<std::size_t>(t_s);
      const double f = t_s - static_cast<double>(i);
      v += path[i] + f * (path[i + 1] - path[i]);
    }
    return v;
  }
};

namespace {

// Pixel and sub-ray directions in the sensor frame, vignetting, dark pixels.
void init_geometry(TofLineSensor::Impl& m, const LensParams& lens) {
  m.n = lens.pixels;
  m.s = lens.subrays_per_pixel;
  m.nsub = m.n * m.s;
  const double pitch = lens.pitch_mm(), f = lens.focal_mm;
  const double mid = 0.5 * m.n;  // the line's middle, in pixel units
  auto dir_at = [&](double pos_px) {
    const double u = (pos_px - mid) * pitch;
    return Eigen::Vector3d(u, 0.0, f).normalized();
  };
  m.sub_dir.resize(static_cast<std::size_t>(m.nsub));
  m.sub_vign.resize(static_cast<std::size_t>(m.nsub));
  for (int j = 0; j < m.nsub; ++j) {
    const Eigen::Vector3d d = dir_at((j + 0.5) / m.s);
    m.sub_dir[static_cast<std::size_t>(j)] = d;
    m.sub_vign[static_cast<std::size_t>(j)] = std::pow(d.z(), lens.vignetting_cos_power);
  }
  m.px_dir.resize(static_cast<std::size_t>(m.n));
  m.px_angle.resize(static_cast<std::size_t>(m.n));
  m.dark.resize(static_cast<std::size_t>(m.n));
  for (int i = 0; i < m.n; ++i) {
    m.px_dir[static_cast<std::size_t>(i)] = dir_at(i + 0.5);
    m.px_angle[static_cast<std::size_t>(i)] =
        std::atan2(m.px_dir[static_cast<std::size_t>(i)].x(), m.px_dir[static_cast<std::size_t>(i)].z());
    m.dark[static_cast<std::size_t>(i)] = (i < lens.dark_pixels || i >= m.n - lens.dark_pixels) ? 1 : 0;
  }
}

// Per-pixel constants (R_sen, V_le, PRNU) from the seed.
void init_pixel_constants(TofLineSensor::Impl& m, const PixelParams& px, std::uint64_t seed) {
  common::XoshiroRandom rng(common::mix_seed(seed, 0x5E45ull, 0));
  for (int i = 0; i < m.n; ++i) {
    m.rsen.push_back(std::max(0.2, px.sensitivity_ratio * (1.0 + px.sensitivity_ratio_sd * rng.normal())));
    m.leak.push_back(std::max(0.0, px.leakage_per_ms * (1.0 + px.leakage_sd * rng.normal())));
    m.prnu.push_back(std::max(0.1, 1.0 + px.prnu_sd * rng.normal()));
  }
  m.skew_ns.assign(static_cast<std::size_t>(m.n), 0.0);
}

// Core blur weights: a Gaussian (sigma) integrated over one pixel's width; the halo's IIR constants.
void init_lens_blur(TofLineSensor::Impl& m, const LensParams& lens) {
  const double sigma = lens.psf_sigma_px;
  const int r_px = static_cast<int>(std::ceil(4.0 * sigma)) + 1;
  m.core_radius = r_px * m.s;
  for (int o = -m.core_radius; o <= m.core_radius; ++o) {
    const double d = (o + 0.5) / m.s - 0.5;  // sub-ray position relative to the pixel centre [px]
    double w;
    if (sigma <= 1e-9) {
      w = (d >= -0.5 && d < 0.5) ? 1.0 : 0.0;
    } else {
      w = normal_cdf((d + 0.5) / sigma) - normal_cdf((d - 0.5) / sigma);
    }
    m.core_w.push_back(w);
  }
  m.halo_h = lens.halo_fraction;
  m.halo_a = std::exp(-1.0 / lens.halo_length_px);
}

// Cumulative distribution of the received pulse on a dt grid over `np`
// samples: the curved pulse s^rise (1-s)^fall on [0, T0], convolved with the
// normalised exponential tail of the slow photo-charge.
std::vector<double> received_pulse_cdf(const EmitterParams& em, double dt, std::size_t np) {
  const double T0 = em.pulse_width_ns, tau = em.diffusion_tail_ns;
  std::vector<double> cdf(np, 0.0);
  const double k = tau > 0 ? std::exp(-dt / tau) : 0.0;
  double y = 0.0, acc = 0.0;
  for (std::size_t i = 0; i < np; ++i) {
    const double t = static_cast<double>(i) * dt;
    double p = 0.0;
    if (t <= T0) {
      const double sn = t / T0;
      p = std::pow(sn, em.pulse_rise_exponent) * std::pow(1.0 - sn, em.pulse_fall_exponent);
      if (em.pulse_rise_exponent == 0.0 && em.pulse_fall_exponent == 0.0) p = 1.0;
    }
    y = k * y + (1.0 - k) * p;  // convolution with the normalised exponential tail
    acc += y * dt;
    cdf[i] = acc;
  }
  for (auto& c : cdf) c /= acc;
  return cdf;
}

// Gate tables over the arrival delay: gate A = [split - T0, split), B = [split, split + T0),
// and their derivatives (for first-order timing shifts).
void init_gate_tables(TofLineSensor::Impl& m, const EmitterParams& em, const PixelParams& px) {
  const double T0 = em.pulse_width_ns, tau = em.diffusion_tail_ns, split = px.gate_split_ns;
  const double dt = m.dtd;
  const double support = T0 + 12.0 * tau + dt;
  const auto np = static_cast<std::size_t>(support / dt) + 2;
  const std::vector<double> cdf = received_pulse_cdf(em, dt, np);
  auto C = [&](double t) {
    const double x = t / dt;
    if (x <= 0.0) return 0.0;
    const auto i = static_cast<std::size_t>(x);
    if (i + 1 >= np) return 1.0;
    return cdf[i] + (x - static_cast<double>(i)) * (cdf[i + 1] - cdf[i]);
  };
  m.td0 = split - 2.0 * T0 - support - 1.0;
  const double td1 = split + T0 + 1.0;
  const auto nt = static_cast<std::size_t>((td1 - m.td0) / dt) + 2;
  m.fa.resize(nt);
  m.fb.resize(nt);
  for (std::size_t i = 0; i < nt; ++i) {
    const double td = m.td0 + static_cast<double>(i) * dt;
    m.fa[i] = C(split - td) - C(split - T0 - td);
    m.fb[i] = C(split + T0 - td) - C(split - td);
  }
  m.dfa.resize(nt);
  m.dfb.resize(nt);
  for (std::size_t i = 0; i < nt; ++i) {
    const std::size_t lo = i > 0 ? i - 1 : i, hi = i + 1 < nt ? i + 1 : i;
    const double span = static_cast<double>(hi - lo) * dt;
    m.dfa[i] = (m.fa[hi] - m.fa[lo]) / span;
    m.dfb[i] = (m.fb[hi] - m.fb[lo]) / span;
  }
}

// The effects the sensor carries, resolved to pointers and per-pixel skews.
void resolve_effects(TofLineSensor::Impl& m, const std::vector<EffectSpec>& effects) {
  for (const auto& fx : effects) {
    std::visit(Overloaded{[&](const TrapDelayEffect& e) { m.trap = &e; },
                          [&](const RangeWalkEffect& e) {
                            m.walk = &e;
                            m.need_derivative = true;
                          },
                          [&](const MaterialBiasEffect& e) { m.material_bias = &e; },
                          [&](const FixedPatternEffect& e) {
                            common::XoshiroRandom r(common::mix_seed(e.seed, 0xF1CEDull, 0));
                            for (int i = 0; i < m.n; ++i) {
                              const double ramp =
                                  m.n > 1 ? (static_cast<double>(i) / (m.n - 1) - 0.5) * e.ramp_ps : 0.0;
                              m.skew_ns[static_cast<std::size_t>(i)] += 1e-3 * (e.sigma_ps * r.normal() + ramp);
                            }
                            m.need_derivative = true;
                          },
                          [&](const TimeDriftEffect& e) { m.time_drift = &e; },
                          [&](const CovariateEffect& e) { m.covariates.push_back(&e); },
                          [&](const TemperatureLagEffect& e) { m.temp_lag = &e; },
                          [&](const ChargeEffect& e) { m.charge.push_back(&e); }},
               fx);
  }
  m.walk_paths.resize(m.covariates.size());
}

}  // namespace

TofLineSensor::TofLineSensor(SensorParams params) : params_(std::move(params)), impl_(std::make_unique<Impl>()) {
  if (const common::Status why = params_.validate(); !why.ok())
    throw std::invalid_argument("sensor parameters: " + why.message);
  Impl& m = *impl_;
  init_geometry(m, params_.lens);
  init_pixel_constants(m, params_.pixel, params_.seed);
  init_lens_blur(m, params_.lens);
  init_gate_tables(m, params_.emitter, params_.pixel);
  resolve_effects(m, params_.effects);
}

TofLineSensor::~TofLineSensor() = default;
TofLineSensor::TofLineSensor(TofLineSensor&&) noexcept = default;
TofLineSensor& TofLineSensor::operator=(TofLineSensor&&) noexcept = default;

bool TofLineSensor::is_dark(int pixel) const { return impl_->dark.at(static_cast<std::size_t>(pixel)) != 0; }
double TofLineSensor::pixel_angle_rad(int pixel) const { return impl_->px_angle.at(static_cast<std::size_t>(pixel)); }
Eigen::Vector3d TofLineSensor::pixel_direction(int pixel) const {
  return impl_->px_dir.at(static_cast<std::size_t>(pixel));
}
double TofLineSensor::sensitivity_ratio(int pixel) const { return impl_->rsen.at(static_cast<std::size_t>(pixel)); }
double TofLineSensor::leakage_per_ms(int pixel) const { return impl_->leak.at(static_cast<std::size_t>(pixel)); }
double TofLineSensor::gate_fraction_a(double td_ns) const { return impl_->lookup(impl_->fa, td_ns); }
double TofLineSensor::gate_fraction_b(double td_ns) const { return impl_->lookup(impl_->fb, td_ns); }

double TofLineSensor::temperature_c(double t_s) const {
  const auto& th = params_.thermal;
  return th.warm_c - (th.warm_c - th.ambient_c) * std::exp(-std::max(0.0, t_s) / th.time_constant_s);
}

namespace {

// Everything of one set that does not depend on the pulse count.
struct PixelPulse {
  std::vector<double> qa, qb, amb;  // per pulse, per pixel
};

}  // namespace

namespace {

constexpr double kMaxRangeM = 30.0;  // rays beyond this see nothing

// The sensor's pose, unpacked once per set.
struct SensorPose {
  Eigen::Matrix3d R;  // sensor to world rotation
  Eigen::Vector3d O;  // receiver (lens centre) in the world
  Eigen::Vector3d E;  // emitter in the world
  SensorPose(const Eigen::Isometry3d& T_ws, const EmitterParams& e)
      : R(T_ws.linear()), O(T_ws.translation()), E(T_ws * Eigen::Vector3d(e.baseline_m, 0.0, 0.0)) {}
};

// Per sub-ray, per pulse: the signal in each gate (and, for effects, the same
// released late and the gates' derivatives), the ambient, and what the ray hit.
struct SubrayCharges {
  std::vector<double> qa, qb, amb, qa2, qb2, dqa, dqb;
  std::vector<double> range;
  std::vector<ObjectId> object;
};

// Extra optical path per material (subsurface scattering effect) [ns].
std::vector<double> material_extra_ns(const TofLineSensor::Impl& m, const World& world) {
  std::vector<double> extra_ns(world.materials().size(), 0.0);
  if (m.material_bias) {
    for (const auto& [name, mm] : m.material_bias->path_mm) {
      if (auto id = world.materials().find(name)) extra_ns[static_cast<std::size_t>(*id)] = mm * 1e-3 * kNsPerM;
    }
  }
  return extra_ns;
}

// Casts every sub-ray: the surface it sees, the ambient it collects, and the
// emitter's light it receives (in the fan, facing the surface, not shadowed)
// split between the gates by its delay.
SubrayCharges cast_subrays(const TofLineSensor::Impl& m, const SensorParams& p, const World& world,
                           const SensorPose& pose, double global_delay_ns) {
  const auto nsub = static_cast<std::size_t>(m.nsub);
  const double c1 = p.emitter.charge_per_pulse_1m / m.s;
  const double amb_c = p.environment.ambient_charge_per_pulse / m.s;
  const bool two = m.trap != nullptr;
  const double trap_shift = two ? m.trap->release_delay_ns : 0.0;
  const std::vector<double> extra_ns = material_extra_ns(m, world);

  SubrayCharges c;
  c.qa.assign(nsub, 0.0);
  c.qb.assign(nsub, 0.0);
  c.amb.assign(nsub, 0.0);
  if (two) {
    c.qa2.assign(nsub, 0.0);
    c.qb2.assign(nsub, 0.0);
  }
  if (m.need_derivative) {
    c.dqa.assign(nsub, 0.0);
    c.dqb.assign(nsub, 0.0);
  }
  c.range.assign(nsub, kNaN);
  c.object.assign(nsub, kNoObject);

  for (std::size_t j = 0; j < nsub; ++j) {
    const Eigen::Vector3d dir = pose.R * m.sub_dir[j];
    const auto hit = world.raycast(Ray{pose.O, dir}, 1e-6, kMaxRangeM);
    if (!hit) continue;
    c.range[j] = hit->t_m;
    c.object[j] = hit->object;
    const Material& mat = world.material_of(*hit);
    c.amb[j] = amb_c * mat.albedo * m.sub_vign[j];
    const Eigen::Vector3d v = hit->point - pose.E;
    const double re = v.norm();
    const Eigen::Vector3d vs = pose.R.transpose() * v;
    if (vs.z() <= 0.0) continue;
    const double fan = fan_weight(std::atan2(vs.x(), vs.z()), p.emitter);
    if (fan <= 0.0) continue;
    const Eigen::Vector3d to_e = -v / re;
    const double cos_i = hit->normal.dot(to_e);
    if (cos_i <= 0.0) continue;
    if (world.occluded(hit->point + 1e-7 * hit->normal, pose.E)) continue;
    const double rf = mat.return_factor(hit->normal, to_e, -dir);
    const double energy = c1 * rf * cos_i * fan * m.sub_vign[j] / (re * hit->t_m);
    const double td = (re + hit->t_m) * kNsPerM + global_delay_ns + extra_ns[static_cast<std::size_t>(hit->material)];
    c.qa[j] = energy * m.lookup(m.fa, td);
    c.qb[j] = energy * m.lookup(m.fb, td);
    if (two) {
      c.qa2[j] = energy * m.lookup(m.fa, td + trap_shift);
      c.qb2[j] = energy * m.lookup(m.fb, td + trap_shift);
    }
    if (m.need_derivative) {
      c.dqa[j] = energy * m.lookup(m.dfa, td);
      c.dqb[j] = energy * m.lookup(m.dfb, td);
    }
  }
  return c;
}

// Sub-rays onto pixels through the lens blur, then per pixel the gain
// (PRNU), the trapped share released late and first-order timing shifts.
void pixel_charges(const TofLineSensor::Impl& m, const SubrayCharges& c, PixelPulse& out) {
  const auto n = static_cast<std::size_t>(m.n);
  const bool two = m.trap != nullptr;
  std::vector<double> binned;
  m.blur(c.qa, out.qa, binned);
  m.blur(c.qb, out.qb, binned);
  m.blur(c.amb, out.amb, binned);
  std::vector<double> pa2, pb2, pda, pdb;
  if (two) {
    m.blur(c.qa2, pa2, binned);
    m.blur(c.qb2, pb2, binned);
  }
  if (m.need_derivative) {
    m.blur(c.dqa, pda, binned);
    m.blur(c.dqb, pdb, binned);
  }

  for (std::size_t i = 0; i < n; ++i) {
    if (m.dark[i]) {
      out.qa[i] = out.qb[i] = out.amb[i] = 0.0;  // masked: no light
      continue;
    }
    const double g = m.prnu[i];
    double a = out.qa[i] * g, b = out.qb[i] * g;
    const double intensity = a + b;
    if (two && intensity > 0.0) {
      // Trapped share released late: eps / (I + eps) of the charge.
      const double share = m.trap->capacity_per_pulse / (intensity + m.trap->capacity_per_pulse);
      a = (1.0 - share) * a + share * pa2[i] * g;
      b = (1.0 - share) * b + share * pb2[i] * g;
    }
    if (m.need_derivative && intensity > 0.0) {
      double shift = m.skew_ns[i];
      if (m.walk) {
        shift += std::clamp(m.walk->ns_per_decade * std::log10(intensity / m.walk->reference_charge_per_pulse),
                            -m.walk->max_ns, m.walk->max_ns);
      }
      // First order in the shift; the total stays (charge moves between gates).
      const double da = shift * pda[i] * g, db = shift * pdb[i] * g;
      a = std::max(0.0, a + da);
      b = std::max(0.0, b + db);
    }
    out.qa[i] = a;
    out.qb[i] = b;
    out.amb[i] *= g;
  }
}

// Ground truth per pixel from its central ray; mixed when the sub-rays of the
// pixel and its neighbours see other surfaces or ranges.
void pixel_truth(const TofLineSensor::Impl& m, const SensorParams& p, const World& world, const SensorPose& pose,
                 const SubrayCharges& c, std::vector<PixelTruth>& truth) {
  const auto n = static_cast<std::size_t>(m.n);
  truth.assign(n, PixelTruth{});
  for (std::size_t i = 0; i < n; ++i) {
    PixelTruth& t = truth[i];
    const Eigen::Vector3d dir = pose.R * m.px_dir[i];
    const auto hit = world.raycast(Ray{pose.O, dir}, 1e-6, kMaxRangeM);
    if (!hit) continue;
    t.range_m = hit->t_m;
    t.object = hit->object;
    t.material = hit->material;
    t.incidence_rad = std::acos(std::clamp(hit->normal.dot(-dir), -1.0, 1.0));
    const Eigen::Vector3d v = hit->point - pose.E;
    const Eigen::Vector3d vs = pose.R.transpose() * v;
    t.lit = vs.z() > 0.0 && fan_weight(std::atan2(vs.x(), vs.z()), p.emitter) > 0.0 && hit->normal.dot(-v) > 0.0 &&
            !world.occluded(hit->point + 1e-7 * hit->normal, pose.E);
    const int s = m.s;
    const int j0 = std::max(0, static_cast<int>(i) * s - s),
              j1 = std::min(m.nsub - 1, static_cast<int>(i) * s + 2 * s - 1);
    for (int j = j0; j <= j1 && !t.mixed; ++j) {
      const auto js = static_cast<std::size_t>(j);
      if (c.object[js] != t.object || std::isnan(c.range[js]) || std::abs(c.range[js] - t.range_m) > 0.02)
        t.mixed = true;
    }
  }
}

}  // namespace

// Computes the per-pulse charges of every pixel; shared by measure() and pulse_charges().
static void compute_pulse(const TofLineSensor::Impl& m, const SensorParams& p, const World& world,
                          const Eigen::Isometry3d& T_ws, double global_delay_ns, PixelPulse& out,
                          std::vector<PixelTruth>* truth) {
  const SensorPose pose(T_ws, p.emitter);
  const SubrayCharges c = cast_subrays(m, p, world, pose, global_delay_ns);
  pixel_charges(m, c, out);
  if (truth) pixel_truth(m, p, world, pose, c, *truth);
}

namespace {

// This sensor's receiver, for crosstalk geometry.
struct Receiver {
  Eigen::Matrix3d R;
  Eigen::Vector3d O;
  double psi_max;  // half the pixels' vertical field of view [rad]
};

// Another sensor's laser sheet.
struct ForeignSheet {
  const ForeignEmitter& fe;
  Eigen::Matrix3d Rj;
  Eigen::Vector3d Ej, nj;  // emitter position, sheet normal
  double half_thick0, half_div;

  explicit ForeignSheet(const ForeignEmitter& e)
      : fe(e),
        Rj(e.T_world_sensor.linear()),
        Ej(e.T_world_sensor * Eigen::Vector3d(e.emitter.baseline_m, 0, 0)),
        nj(Rj.col(1)),
        half_thick0(0.5e-3 * e.emitter.sheet_thickness_mm),
        half_div(std::tan(0.5 * deg(e.emitter.sheet_divergence_deg))) {}

  // Whether the sheet lights `pt` (inside its thickness and fan, facing it, unshadowed).
  bool lights(const World& world, const Eigen::Vector3d& pt, const Eigen::Vector3d& normal, double& re,
              Eigen::Vector3d& to_e, double& fan) const {
    const Eigen::Vector3d v = pt - Ej;
    re = v.norm();
    const Eigen::Vector3d vs = Rj.transpose() * v;
    if (vs.z() <= 0.0 || std::abs(vs.y()) > half_thick0 + re * half_div) return false;
    fan = fan_weight(std::atan2(vs.x(), vs.z()), fe.emitter);
    if (fan <= 0.0) return false;
    to_e = -v / re;
    if (normal.dot(to_e) <= 0.0) return false;
    return !world.occluded(pt + 1e-7 * normal, Ej);
  }
};

// Which own pulses could catch this emitter's light at all (timing only, cheap):
// (own pulse, offset of the other's nearest pulse [ns]).
std::vector<std::pair<int, double>> crosstalk_candidates(const TofLineSensor::Impl& m, const ForeignEmitter& fe,
                                                         double t0_shared, int pulse_count, double own_rate) {
  const double fj = fe.pulse_rate_hz;
  const double td_lo = m.td0, td_hi = m.td0 + m.dtd * static_cast<double>(m.fa.size());
  auto on_at = [&](double t) {
    for (const auto& [a, b] : fe.on_intervals)
      if (t >= a && t < b) return true;
    return false;
  };
  const double max_path_ns = 2.0 * kMaxRangeM * kNsPerM;
  std::vector<std::pair<int, double>> candidates;
  for (int k = 0; k < pulse_count; ++k) {
    const double t = t0_shared + k / own_rate;
    if (!on_at(t)) continue;
    const double q = std::round((t - fe.first_pulse_s) * fj);
    const double o_ns = (fe.first_pulse_s + q / fj - t) * 1e9;
    if (o_ns + max_path_ns < td_lo || o_ns > td_hi) continue;
    candidates.emplace_back(k, o_ns);
  }
  return candidates;
}

Eigen::Vector3d pixel_ray(const Receiver& rx, double th, double psi) {
  return Eigen::Vector3d(rx.R *
                         Eigen::Vector3d(std::sin(th) * std::cos(psi), std::sin(psi), std::cos(th) * std::cos(psi)));
}

// The vertical angle within a pixel's view (ray angle `th`) at which the
// surface it sees lies on the sheet: a scan over 9 angles, then bisection
// (NaN: nowhere).
double sheet_crossing_psi(const World& world, const Receiver& rx, const ForeignSheet& sheet, double th) {
  auto g_at = [&](double psi) {
    const auto h = world.raycast(Ray{rx.O, pixel_ray(rx, th, psi)}, 1e-6, kMaxRangeM);
    return h ? sheet.nj.dot(h->point - sheet.Ej) : kNaN;
  };
  constexpr int K = 9;
  double prev_psi = 0, prev_g = kNaN;
  for (int k = 0; k < K; ++k) {
    const double psi = -rx.psi_max + 2.0 * rx.psi_max * k / (K - 1);
    const double g = g_at(psi);
    if (!std::isnan(g) && std::abs(g) < 1e-9) return psi;
    if (!std::isnan(g) && !std::isnan(prev_g) && (g > 0) != (prev_g > 0)) {
      double lo = prev_psi, hi = psi, glo = prev_g;
      for (int it = 0; it < 12; ++it) {
        const double mid = 0.5 * (lo + hi);
        const double gm = g_at(mid);
        if (std::isnan(gm)) break;
        if ((gm > 0) == (glo > 0)) {
          lo = mid;
          glo = gm;
        } else {
          hi = mid;
        }
      }
      return 0.5 * (lo + hi);
    }
    prev_psi = psi;
    prev_g = g;
  }
  return kNaN;
}

// Per pixel, the energy one pulse of the sheet deposits off the scene, and its path delay [ns].
void sheet_energy(const TofLineSensor::Impl& m, const SensorParams& p, const World& world, const Receiver& rx,
                  const ForeignSheet& sheet, std::vector<double>& energy, std::vector<double>& path_ns) {
  const double c1 = p.emitter.charge_per_pulse_1m;
  for (std::size_t i = 0; i < static_cast<std::size_t>(m.n); ++i) {
    if (m.dark[i]) continue;
    const double best_psi = sheet_crossing_psi(world, rx, sheet, m.px_angle[i]);
    if (std::isnan(best_psi)) continue;
    const Eigen::Vector3d dir = pixel_ray(rx, m.px_angle[i], best_psi);
    const auto hit = world.raycast(Ray{rx.O, dir}, 1e-6, kMaxRangeM);
    if (!hit) continue;
    double re = 0, fan = 0;
    Eigen::Vector3d to_e;
    if (!sheet.lights(world, hit->point, hit->normal, re, to_e, fan)) continue;
    const Material& mat = world.material_of(*hit);
    const double rf = mat.return_factor(hit->normal, to_e, -dir);
    energy[i] = c1 * rf * hit->normal.dot(to_e) * fan * std::pow(m.px_dir[i].z(), p.lens.vignetting_cos_power) /
                (re * hit->t_m) * m.prnu[i];
    path_ns[i] = (re + hit->t_m) * kNsPerM;
  }
}

// The other emitter seen directly: its whole beam into one pixel (saturates).
void direct_beam_energy(const TofLineSensor::Impl& m, const SensorParams& p, const World& world, const Receiver& rx,
                        const ForeignSheet& sheet, std::vector<double>& energy, std::vector<double>& path_ns) {
  const double f = p.lens.focal_mm, pitch = p.lens.pitch_mm();
  const Eigen::Vector3d ve = rx.R.transpose() * (sheet.Ej - rx.O);
  const double r = ve.norm();
  if (!(ve.z() > 0.0 && std::abs(ve.y()) <= ve.z() * std::tan(rx.psi_max))) return;
  const double pos = ve.x() / ve.z() * f / pitch + 0.5 * m.n;
  const auto i = static_cast<long>(std::floor(pos));
  if (!(i >= 0 && i < m.n && !m.dark[static_cast<std::size_t>(i)])) return;
  const Eigen::Vector3d vj = sheet.Rj.transpose() * (rx.O - sheet.Ej);
  if (vj.z() > 0.0 && std::abs(vj.y()) <= sheet.half_thick0 + r * sheet.half_div &&
      fan_weight(std::atan2(vj.x(), vj.z()), sheet.fe.emitter) > 0.0 && !world.occluded(rx.O, sheet.Ej)) {
    constexpr double kDirectGain = 1e4;  // a beam into the aperture vs. a white diffuse return
    energy[static_cast<std::size_t>(i)] += p.emitter.charge_per_pulse_1m * kDirectGain / (r * r);
    path_ns[static_cast<std::size_t>(i)] = r * kNsPerM;
  }
}

// Adds the candidate pulses' charge that lands inside the gates to the
// read-out each pulse counts in; marks the own pulses that caught light.
void accumulate_crosstalk(const TofLineSensor::Impl& m, std::span<const int> pulses,
                          const std::vector<std::pair<int, double>>& candidates, const std::vector<double>& energy,
                          const std::vector<double>& path_ns, std::vector<double>& inc_a, std::vector<double>& inc_b,
                          std::vector<char>& pulse_hit) {
  const auto n = static_cast<std::size_t>(m.n);
  const std::size_t nr = pulses.size();
  for (const auto& [k, o_ns] : candidates) {
    std::size_t rk = 0;
    while (rk < nr && pulses[rk] <= k) ++rk;  // the first read-out this pulse counts in
    bool any = false;
    for (std::size_t i = 0; i < n; ++i) {
      if (energy[i] <= 0.0) continue;
      const double td = o_ns + path_ns[i];
      const double fa = m.lookup(m.fa, td), fb = m.lookup(m.fb, td);
      if (fa <= 0.0 && fb <= 0.0) continue;
      inc_a[rk * n + i] += energy[i] * fa;
      inc_b[rk * n + i] += energy[i] * fb;
      any = true;
    }
    if (any) pulse_hit[static_cast<std::size_t>(k)] = 1;
  }
}

}  // namespace

// Light of other sensors' line lasers that reaches this sensor's pixels while
// its gates are open (thesis 6.2.1). For each pixel, the point of the scene
// that lies on the other sensor's laser sheet inside this pixel's field of
// view (a root search over the pixel's vertical angle), plus the other
// emitter itself when it shines straight into this receiver. Per own pulse,
// the other sensor's nearest pulse sets the arrival time in this sensor's
// gates; the pulses whose light lands inside the gates add charge.
static void add_crosstalk(const TofLineSensor::Impl& m, const SensorParams& p, const World& world,
                          const Eigen::Isometry3d& T_ws, double t0_shared, std::span<const int> pulses,
                          std::span<const ForeignEmitter> others, std::vector<double>& xa, std::vector<double>& xb,
                          int& hit_pulses) {
  const auto n = static_cast<std::size_t>(m.n);
  const std::size_t nr = pulses.size();
  const Receiver rx{T_ws.linear(), T_ws.translation(), std::atan(0.5 * p.lens.pixel_height_mm / p.lens.focal_mm)};
  std::vector<double> inc_a(n * nr, 0.0), inc_b(n * nr, 0.0);
  std::vector<char> pulse_hit(static_cast<std::size_t>(pulses.back()), 0);
  for (const ForeignEmitter& fe : others) {
    if (!(fe.pulse_rate_hz > 0.0) || fe.on_intervals.empty()) continue;
    const auto candidates = crosstalk_candidates(m, fe, t0_shared, pulses.back(), p.emitter.pulse_rate_hz);
    if (candidates.empty()) continue;
    const ForeignSheet sheet(fe);
    std::vector<double> energy(n, 0.0), path_ns(n, 0.0);
    sheet_energy(m, p, world, rx, sheet, energy, path_ns);
    direct_beam_energy(m, p, world, rx, sheet, energy, path_ns);
    accumulate_crosstalk(m, pulses, candidates, energy, path_ns, inc_a, inc_b, pulse_hit);
  }
  for (std::size_t r = 0; r < nr; ++r) {
    for (std::size_t i = 0; i < n; ++i) {
      xa[r * n + i] = inc_a[r * n + i] + (r > 0 ? xa[(r - 1) * n + i] : 0.0);
      xb[r * n + i] = inc_b[r * n + i] + (r > 0 ? xb[(r - 1) * n + i] : 0.0);
    }
  }
  hit_pulses = 0;
  for (char c : pulse_hit) hit_pulses += c;
}

PulseCharges TofLineSensor::pulse_charges(const World& world, const Eigen::Isometry3d& T_world_sensor, double t_s,
                                          std::vector<PixelTruth>* truth) const {
  const auto& th = params_.thermal;
  PixelPulse pp;
  // Same global delay as measure() at this instant.
  double delay = 0.0;
  {
    const Impl& m = *impl_;
    double td = temperature_c(t_s);
    if (m.temp_lag) {
      const double tau = th.time_constant_s, tl = m.temp_lag->time_constant_s, D = th.warm_c - th.ambient_c;
      td = std::abs(tau - tl) < 1e-9
               ? th.warm_c - D * (1.0 + t_s / tau) * std::exp(-t_s / tau)
               : th.warm_c - D * (tau * std::exp(-t_s / tau) - tl * std::exp(-t_s / tl)) / (tau - tl);
    }
    delay += th.delay_drift_ns_per_c * (td - th.reference_c);
    if (m.time_drift) {
      delay += m.time_drift->ns_per_hour * t_s / 3600.0 +
               m.time_drift->sine_amplitude_ns * std::sin(2.0 * M_PI * t_s / m.time_drift->sine_period_s);
    }
    for (std::size_t k = 0; k < m.covariates.size(); ++k) {
      delay += m.covariates[k]->ns_per_unit * (m.covariate_value(k, t_s, params_.seed) - m.covariates[k]->mean);
    }
  }
  compute_pulse(*impl_, params_, world, T_world_sensor, delay, pp, truth);
  return PulseCharges{std::move(pp.qa), std::move(pp.qb), std::move(pp.amb)};
}

namespace {

void check_pulse_schedule(std::span<const int> pulses) {
  if (pulses.empty()) throw std::invalid_argument("measure: no read-out pulse counts");
  for (std::size_t k = 0; k < pulses.size(); ++k) {
    if (pulses[k] <= 0 || (k > 0 && pulses[k] <= pulses[k - 1]))
      throw std::invalid_argument("measure: read-out pulse counts must be positive and increasing");
  }
}

// The read-outs of pixel i: charges accumulate over the pulses (with shot and
// transfer noise that accumulate too, read-outs being non-destructive), plus
// leakage and crosstalk; each read-out then goes through the read-out chain.
void read_out_pixel(const TofLineSensor::Impl& m, const TofLineSensor& sensor, const PixelParams& px, std::size_t i,
                    const PulseCharges& pc, std::span<const int> pulses, const std::vector<double>& xa,
                    const std::vector<double>& xb, bool noise, common::XoshiroRandom& rng, SensorSet& set) {
  const auto n = static_cast<std::size_t>(m.n);
  const double sa = pc.qa[i] + pc.ambient[i], sb = pc.qb[i] + pc.ambient[i];
  double prev_a = 0.0, prev_b = 0.0, noise_a = 0.0, noise_b = 0.0;
  int prev_p = 0;
  const double k_transfer = px.transfer_noise_per_pulse * px.transfer_noise_per_pulse;
  for (std::size_t k = 0; k < pulses.size(); ++k) {
    const double p = pulses[k];
    const double t_ms = 1e3 * sensor.accumulation_time_s(pulses[k]);
    const double leak = m.leak[i] * t_ms;
    double mean_a = p * sa + xa[k * n + i] + leak;
    double mean_b = p * sb + xb[k * n + i] + leak;
    apply_charge_effects(m.charge, static_cast<int>(i), pulses[k], set.covariates, mean_a, mean_b);
    double a = mean_a, b = mean_b;
    if (noise) {
      const double cycles = pulses[k] - prev_p;
      noise_a += std::sqrt(px.shot_noise_gain * std::max(0.0, mean_a - prev_a) + k_transfer * cycles) * rng.normal();
      noise_b += std::sqrt(px.shot_noise_gain * std::max(0.0, mean_b - prev_b) + k_transfer * cycles) * rng.normal();
      a = mean_a + noise_a;
      b = mean_b + noise_b;
    }
    prev_a = mean_a;
    prev_b = mean_b;
    prev_p = pulses[k];
    a /= m.rsen[i];  // Eq. 3.16: a * R_sen - V_le and b - V_le compare like with like
    if (noise) {
      a += px.read_noise * rng.normal();
      b += px.read_noise * rng.normal();
    }
    // The capacitor saturates first (it holds no more than its swing); the read-out's
    // transfer curve then maps what it holds, so a saturated capacitor reads a
    // plateau, never a value that falls again with more charge.
    a = compress(a, px.knee, px.full_scale);
    b = compress(b, px.knee, px.full_scale);
    if (px.nonlinearity > 0.0) {
      a -= px.nonlinearity * a * std::abs(a) / px.full_scale;
      b -= px.nonlinearity * b * std::abs(b) / px.full_scale;
    }
    a += px.adc_offset_a;
    b += px.adc_offset_b;
    if (noise) {
      a = std::round(a / px.adc_lsb) * px.adc_lsb;
      b = std::round(b / px.adc_lsb) * px.adc_lsb;
    }
    set.readouts[k].a[i] = std::clamp(a, -px.adc_max, px.adc_max);
    set.readouts[k].b[i] = std::clamp(b, -px.adc_max, px.adc_max);
  }
}

}  // namespace

SensorSet TofLineSensor::measure(const World& world, const Eigen::Isometry3d& T_world_sensor, double t_start_s,
                                 std::span<const int> pulses, std::uint64_t index,
                                 std::span<const ForeignEmitter> others, const MeasureOptions& options) const {
  const Impl& m = *impl_;
  const auto n = static_cast<std::size_t>(m.n);
  check_pulse_schedule(pulses);
  const int p_max = pulses.back();
  const double t_mid = t_start_s + 0.5 * accumulation_time_s(p_max);

  SensorSet set;
  set.index = index;
  set.t_start_s = t_start_s;
  set.t_end_s = t_start_s + accumulation_time_s(p_max);
  set.laser_on = options.laser_on;
  set.T_world_sensor = T_world_sensor;
  for (std::size_t k = 0; k < m.covariates.size(); ++k) {
    set.covariates[m.covariates[k]->name] = m.covariate_value(k, t_mid, params_.seed);
  }

  // Per-pulse charges at the middle of the accumulation (the scene is static during a set).
  PulseCharges pc = pulse_charges(world, T_world_sensor, t_mid, &set.truth);
  if (!options.laser_on) {
    std::fill(pc.qa.begin(), pc.qa.end(), 0.0);
    std::fill(pc.qb.begin(), pc.qb.end(), 0.0);
  }

  // Crosstalk: other sensors' pulses that land inside this sensor's gates.
  const std::size_t nr = pulses.size();
  std::vector<double> xa(n * nr, 0.0), xb(n * nr, 0.0);  // cumulative per read-out
  if (!others.empty()) {
    add_crosstalk(m, params_, world, T_world_sensor, t_start_s + options.clock_offset_s, pulses, others, xa, xb,
                  set.crosstalk_pulses);
  }

  common::XoshiroRandom rng(common::mix_seed(params_.seed, 0xA11CEull, index));
  set.readouts.resize(nr);
  for (std::size_t k = 0; k < nr; ++k) {
    auto& r = set.readouts[k];
    r.pulses = pulses[k];
    r.t_s = t_start_s + accumulation_time_s(pulses[k]);
    r.a.resize(n);
    r.b.resize(n);
  }
  for (std::size_t i = 0; i < n; ++i)
    read_out_pixel(m, *this, params_.pixel, i, pc, pulses, xa, xb, options.noise, rng, set);

  set.true_temperature_c = temperature_c(set.t_end_s);
  double reading = set.true_temperature_c;
  if (options.noise) reading += params_.thermal.reading_noise_c * rng.normal();
  set.temperature_c = std::round(reading * 10.0) / 10.0;
  return set;
}

}  // namespace tinyline::sim
