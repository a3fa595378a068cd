// SPDX-License-Identifier: Apache-2.0
#include <sim/rgbd_camera.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <tinyline/common/random.hpp>

namespace tinyline::sim {

namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

// Counter-based randomness: every (seed, frame, stream, index) gives the same
// number on every platform (std::normal_distribution does not promise that).
using common::splitmix64;
double uniform01(std::uint64_t key) { return common::unit_open(splitmix64(key)); }
// Unit-variance noise from one hash: the sum of four 16-bit uniforms
// (Irwin-Hall), close enough to a Gaussian for sensor noise and several
// times cheaper than Box-Muller at a million draws per frame.
double gaussian(std::uint64_t key) {
  const std::uint64_t h = splitmix64(key);
  const double s = static_cast<double>((h & 0xffff) + ((h >> 16) & 0xffff) + ((h >> 32) & 0xffff) + (h >> 48));
  return (s / 65536.0 - 2.0) * 1.7320508075688772;  // sqrt(12 / 4)
}
std::uint64_t stream_key(std::uint64_t seed, std::uint64_t frame, std::uint64_t stream) {
  return splitmix64(splitmix64(seed * 0x632be59bd9b4e019ULL + frame) + stream * 0x85ebca6b);
}

// Smooth noise field of unit variance with a correlation length of about
// `cell` pixels: unit Gaussians on a coarse grid, bilinearly interpolated and
// rescaled (interpolation lowers the variance between grid nodes).
class CorrelatedField {
 public:
  CorrelatedField(int width, int height, int cell, std::uint64_t key)
      : cell_(std::max(1, cell)),
        gw_(width / cell_ + 2),
        gh_(height / cell_ + 2),
        g_(static_cast<std::size_t>(gw_ * gh_)) {
    for (std::size_t i = 0; i < g_.size(); ++i) g_[i] = gaussian(key + i);
  }
  double at(int u, int v) const {
    const double x = static_cast<double>(u) / cell_, y = static_cast<double>(v) / cell_;
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const double fx = x - x0, fy = y - y0;
    auto g = [&](int i, int j) { return g_[static_cast<std::size_t>(j * gw_ + i)]; };
    const double val = (1 - fx) * (1 - fy) * g(x0, y0) + fx * (1 - fy) * g(x0 + 1, y0) + (1 - fx) * fy * g(x0, y0 + 1) +
                       fx * fy * g(x0 + 1, y0 + 1);
    // Variance of the bilinear mix of four unit Gaussians.
    const double var = ((1 - fx) * (1 - fx) + fx * fx) * ((1 - fy) * (1 - fy) + fy * fy);
    return val / std::sqrt(var);
  }

 private:
  int cell_, gw_, gh_;
  std::vector<double> g_;
};

// Bounding sphere of an object in the world (radius inf: unbounded plane).
struct Bound {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = kInf;
};

Bound bound_of(const Object& o) {
  Bound b;
  const auto& T = o.T_world_object;
  if (const auto* s = std::get_if<SphereShape>(&o.shape)) {
    b = {T.translation(), s->radius_m};
  } else if (const auto* r = std::get_if<RodShape>(&o.shape)) {
    b = {T * (0.5 * (r->p0 + r->p1)), 0.5 * (r->p1 - r->p0).norm() + r->radius_m};
  } else if (const auto* x = std::get_if<BoxShape>(&o.shape)) {
    b = {T.translation(), 0.5 * x->size_m.norm()};
  } else if (const auto* c = std::get_if<CylinderShape>(&o.shape)) {
    b = {T.translation(), std::hypot(c->radius_m, 0.5 * c->length_m)};
  } else if (const auto* p = std::get_if<PlaneShape>(&o.shape)) {
    if (std::isfinite(p->size_m.x()) && std::isfinite(p->size_m.y())) b = {T.translation(), 0.5 * p->size_m.norm()};
  } else if (const auto* m = std::get_if<MeshShape>(&o.shape)) {
    Eigen::AlignedBox3d box;
    for (const auto& v : m->vertices) box.extend(v);
    if (!box.isEmpty()) b = {T * box.center(), 0.5 * box.diagonal().norm()};
  }
  b.radius *= 1.0 + 1e-9;
  b.radius += 1e-9;
  return b;
}

// A world holding only some objects of another (same material ids), and the
// map from its object ids back to the original ones.
struct SubWorld {
  World world;
  std::vector<ObjectId> original;
  SubWorld(const World& full, const std::vector<ObjectId>& ids) : world(full.materials()) {
    original = ids;
    for (ObjectId id : ids) world.add(full.object(id));
  }
};

// Does the sphere meet the cone from `apex` along unit `axis` with half angle `half`?
bool sphere_meets_cone(const Bound& b, const Eigen::Vector3d& apex, const Eigen::Vector3d& axis, double half) {
  if (!std::isfinite(b.radius)) return true;
  const Eigen::Vector3d v = b.centre - apex;
  const double dist = v.norm();
  if (dist <= b.radius) return true;
  const double ang = std::acos(std::clamp(v.dot(axis) / dist, -1.0, 1.0));
  return ang <= half + std::asin(b.radius / dist);
}

// Does the sphere meet the capsule of radius `r` around segment a-b?
bool sphere_meets_capsule(const Bound& s, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double r) {
  if (!std::isfinite(s.radius)) return true;
  const Eigen::Vector3d ab = b - a;
  const double l2 = ab.squaredNorm();
  const double t = l2 > 0 ? std::clamp((s.centre - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  return (s.centre - (a + t * ab)).norm() <= s.radius + r;
}

const Gloss* gloss_of(const std::vector<Gloss>& gloss, const std::string& material) {
  for (const auto& g : gloss)
    if (material.compare(0, g.material_prefix.size(), g.material_prefix) == 0) return &g;
  return nullptr;
}

}  // namespace

bool DepthDistortion::enabled() const {
  return z_slope != 0.0 || std::any_of(spatial_m.begin(), spatial_m.end(), [](double c) { return c != 0.0; });
}

double DepthDistortion::offset_m(double xn, double yn, double z_m) const {
  const auto& c = spatial_m;
  return c[0] + c[1] * xn + c[2] * yn + c[3] * xn * xn + c[4] * xn * yn + c[5] * yn * yn + z_slope * z_m;  // Eq. 4.4
}

common::Status RgbdCameraParams::validate() const {
  const auto& k = intrinsics;
  auto finite_pos = [](double x) { return std::isfinite(x) && x > 0.0; };
  if (k.width < 2 || k.height < 2) return common::Status::invalid("intrinsics: width and height must be >= 2 px");
  if (!finite_pos(k.fx) || !finite_pos(k.fy))
    return common::Status::invalid("intrinsics: fx and fy must be finite and > 0");
  if (!std::isfinite(k.cx) || !std::isfinite(k.cy))
    return common::Status::invalid("intrinsics: cx and cy must be finite");
  if (!finite_pos(min_depth_m) || !(max_depth_m > min_depth_m) || !std::isfinite(max_depth_m))
    return common::Status::invalid("min_depth_m must be > 0 and below max_depth_m (finite)");
  if (!finite_pos(projector_baseline_m)) return common::Status::invalid("projector_baseline_m must be > 0");
  if (!(disparity_noise_px >= 0) || !(disparity_noise_correlated_px >= 0) || !(disparity_step_px >= 0))
    return common::Status::invalid("disparity noise and step must be >= 0");
  if (correlation_window_px < 1) return common::Status::invalid("correlation_window_px must be >= 1");
  if (!(edge_jump_m > 0) || !(edge_jump_per_m >= 0))
    return common::Status::invalid("edge_jump_m must be > 0 and edge_jump_per_m >= 0");
  if (!(edge_dropout >= 0 && edge_dropout <= 1)) return common::Status::invalid("edge_dropout must be in [0, 1]");
  if (!(grazing_start_deg >= 0 && grazing_start_deg < grazing_end_deg && grazing_end_deg <= 90))
    return common::Status::invalid("grazing angles must satisfy 0 <= start < end <= 90 deg");
  if (!light_position_m.allFinite()) return common::Status::invalid("light_position_m must be finite");
  if (!(light_intensity >= 0) || !(ambient >= 0) || !(exposure > 0) || !(colour_noise_dn >= 0))
    return common::Status::invalid("light_intensity, ambient, colour_noise_dn must be >= 0 and exposure > 0");
  for (const auto& g : gloss)
    if (!(g.strength >= 0 && g.strength <= 1) || !(g.exponent >= 1))
      return common::Status::invalid("gloss: strength in [0, 1], exponent >= 1");
  for (double c : distortion.spatial_m)
    if (!std::isfinite(c)) return common::Status::invalid("distortion coefficients must be finite");
  if (!std::isfinite(distortion.z_slope)) return common::Status::invalid("distortion z_slope must be finite");
  return common::Status{};
}

Eigen::Vector3f RgbdFrame::point(std::size_t i) const {
  const float z = depth_m[i];
  const int u = static_cast<int>(i % static_cast<std::size_t>(width)),
            v = static_cast<int>(i / static_cast<std::size_t>(width));
  return {static_cast<float>((u - intrinsics.cx) / intrinsics.fx) * z,
          static_cast<float>((v - intrinsics.cy) / intrinsics.fy) * z, z};
}

std::size_t RgbdFrame::num_valid() const {
  return static_cast<std::size_t>(std::count_if(depth_m.begin(), depth_m.end(), [](float z) { return z == z; }));
}

RgbdCamera::RgbdCamera(RgbdCameraParams params) : params_(std::move(params)) {
  if (const common::Status why = params_.validate(); !why.ok())
    throw std::invalid_argument("RgbdCamera: " + why.message);
}

bool RgbdCamera::project(const Eigen::Vector3d& p, Eigen::Vector2d& uv) const {
  if (!(p.z() > 0)) return false;
  const auto& k = params_.intrinsics;
  uv = {k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy};
  return true;
}

namespace {

// One frame in the making: the steps of RgbdCamera::render share the
// camera's pose, the per-pixel buffers and the frame's noise streams.
class FrameRenderer {
 public:
  FrameRenderer(const RgbdCameraParams& params, const World& world, const Eigen::Isometry3d& T_world_camera,
                std::uint64_t frame_index, RgbdFrame& frame)
      : P(params),
        K(params.intrinsics),
        world_(world),
        f(frame),
        W(K.width),
        H(K.height),
        N(static_cast<std::size_t>(W) * static_cast<std::size_t>(H)),
        R(T_world_camera.linear()),
        eye(T_world_camera.translation()),
        projector(T_world_camera * Eigen::Vector3d(P.projector_baseline_m, 0, 0)),
        cos_graze_start(std::cos(P.grazing_start_deg * M_PI / 180.0)),
        cos_graze_end(std::cos(P.grazing_end_deg * M_PI / 180.0)),
        frame_index_(frame_index),
        key_dropout(stream_key(P.seed, frame_index, 1)),
        key_white(stream_key(P.seed, frame_index, 2)),
        key_colour(stream_key(P.seed, frame_index, 3)),
        key_graze(stream_key(P.seed, frame_index, 4)),
        z_true(N, kNaNf),
        has_depth(N, 0),
        linear_rgb(N),
        gloss_by_material(world.materials().size(), nullptr) {
    f.width = W;
    f.height = H;
    f.intrinsics = K;
    f.T_world_camera = T_world_camera;
    f.depth_m.assign(N, kNaNf);
    f.true_depth_m.assign(N, kNaNf);
    f.rgb.assign(N, {0, 0, 0});
    f.object.assign(N, kNoObject);
    for (std::size_t m = 0; m < world.materials().size(); ++m)
      gloss_by_material[m] = gloss_of(P.gloss, world.materials().get(static_cast<MaterialId>(m)).name);
  }

  // Every pixel's ray against the whole world.
  void cast_all() {
    for (int v = 0; v < H; ++v) {
      for (int u = 0; u < W; ++u) {
        const std::size_t i = pixel(u, v);
        const Eigen::Vector3d dir_c = K.ray(u, v);
        const Ray ray{eye, R * dir_c};
        const auto hit = world_.raycast(ray);
        if (!hit) {
          linear_rgb[i] = P.background_rgb.cast<float>();
          continue;
        }
        shade(i, ray, dir_c.z(), *hit, hit->object, world_);
      }
    }
  }

  // Tiles: each casts its rays against the objects whose bounding spheres
  // meet the tile's cone of rays, and its shadow rays against the objects
  // near the segments from its hits to the lamp and to the projector.
  void cast_tiled() {
    bounds_.resize(world_.size());
    for (std::size_t k = 0; k < world_.size(); ++k) bounds_[k] = bound_of(world_.object(static_cast<ObjectId>(k)));
    hits_.resize(kTile * kTile);
    hit_ok_.resize(kTile * kTile);
    for (int v0 = 0; v0 < H; v0 += kTile) {
      for (int u0 = 0; u0 < W; u0 += kTile) render_tile(u0, v0);
    }
  }

  // Silhouette edges: the matching window straddles a depth jump (a pixel
  // with no surface behind it counts as an infinite jump).
  [[nodiscard]] std::vector<std::uint8_t> silhouette_edges() const {
    std::vector<std::uint8_t> edge(N, 0);
    for (int v = 0; v < H; ++v) {
      for (int u = 0; u < W; ++u) {
        const std::size_t i = static_cast<std::size_t>(v * W + u);
        if (has_depth[i]) edge[i] = depth_jumps_around(u, v);
      }
    }
    return edge;
  }

  // The stereo depth: disparity with white and correlated noise, quantised,
  // back to depth, distorted; dropped on edges at random and out of range.
  void measure_depth(const std::vector<std::uint8_t>& edge) {
    const double fb = K.fx * P.projector_baseline_m;  // disparity = fb / z [px]
    const CorrelatedField field(W, H, P.correlation_window_px, stream_key(P.seed, frame_index_, 5));
    const bool distort = P.distortion.enabled();
    for (int v = 0; v < H; ++v) {
      for (int u = 0; u < W; ++u) {
        const std::size_t i = static_cast<std::size_t>(v * W + u);
        f.true_depth_m[i] = z_true[i];
        if (!has_depth[i]) continue;
        if (edge[i] && uniform01(key_dropout + i) < P.edge_dropout) continue;
        const double z = z_true[i];
        double d =
            fb / z + P.disparity_noise_px * gaussian(key_white + i) + P.disparity_noise_correlated_px * field.at(u, v);
        if (P.disparity_step_px > 0) d = std::round(d / P.disparity_step_px) * P.disparity_step_px;
        if (!(d > 0)) continue;
        double zm = fb / d;
        if (distort) zm += P.distortion.offset_m((u - K.cx) / W, (v - K.cy) / H, zm);
        if (zm < P.min_depth_m || zm > P.max_depth_m) continue;
        f.depth_m[i] = static_cast<float>(zm);
      }
    }
  }

  // Exposure, sRGB (through a table: a pow per channel per pixel is a fifth
  // of the frame) and colour noise.
  void encode_colour() {
    for (std::size_t i = 0; i < N; ++i) {
      for (int ch = 0; ch < 3; ++ch) {
        const double dn = srgb_lut(P.exposure * static_cast<double>(linear_rgb[i][ch])) +
                          P.colour_noise_dn * gaussian(key_colour + 3 * i + static_cast<std::uint64_t>(ch));
        f.rgb[i][static_cast<std::size_t>(ch)] = static_cast<std::uint8_t>(std::clamp(std::lround(dn), 0L, 255L));
      }
    }
  }

 private:
  static constexpr int kTile = 8;

  [[nodiscard]] std::size_t pixel(int u, int v) const {
    return static_cast<std::size_t>(v) * static_cast<std::size_t>(W) + static_cast<std::size_t>(u);
  }
  [[nodiscard]] std::size_t tile_slot(int u, int v, int u0, int v0) const {
    return static_cast<std::size_t>((v - v0) * kTile + (u - u0));
  }

  static double srgb_lut(double lin) {
    constexpr int kLut = 4096;
    static const std::vector<float> lut = [] {
      std::vector<float> t(kLut + 1);
      for (int k = 0; k <= kLut; ++k)
        t[static_cast<std::size_t>(k)] = static_cast<float>(srgb_encode(static_cast<double>(k) / kLut));
      return t;
    }();
    const double x = std::clamp(lin, 0.0, 1.0) * kLut;
    const int k = std::min(kLut - 1, static_cast<int>(x));
    const double a = x - k;
    return (1 - a) * lut[static_cast<std::size_t>(k)] + a * lut[static_cast<std::size_t>(k + 1)];
  }

  [[nodiscard]] bool depth_jumps_around(int u, int v) const {
    const double z = z_true[static_cast<std::size_t>(v * W + u)];
    const double thr = P.edge_jump_m + P.edge_jump_per_m * z;
    for (int dv = -1; dv <= 1; ++dv) {
      for (int du = -1; du <= 1; ++du) {
        const int uu = u + du, vv = v + dv;
        if (uu < 0 || vv < 0 || uu >= W || vv >= H) continue;
        const float zn = z_true[static_cast<std::size_t>(vv * W + uu)];
        if (!(std::abs(zn - z) <= thr)) return true;  // NaN (nothing there) is a jump too
      }
    }
    return false;
  }

  // Shades pixel i from its hit; decides whether the pattern returns depth.
  // `occluders` answers shadow rays (the full world or a tile's share of it).
  void shade(std::size_t i, const Ray& ray, double dir_z, const Hit& hit, ObjectId original, const World& occluders) {
    f.object[i] = original;
    const double z = hit.t_m * dir_z;
    z_true[i] = static_cast<float>(z);
    const Eigen::Vector3d to_eye = -ray.dir;
    shade_colour(i, to_eye, hit, occluders);
    // Depth: in range, not grazing, and lit by the projector.
    if (z < P.min_depth_m || z > P.max_depth_m) return;
    const double cos_inc = std::abs(hit.normal.dot(to_eye));
    if (cos_inc < cos_graze_end) return;
    if (cos_inc < cos_graze_start) {
      const double keep = (cos_inc - cos_graze_end) / (cos_graze_start - cos_graze_end);
      if (uniform01(key_graze + i) > keep) return;
    }
    if (P.projector_shadow && occluders.occluded(hit.point + 1e-5 * hit.normal, projector)) return;
    has_depth[i] = 1;
  }

  // Colour: ambient + lamp (Lambert, shadowed) + highlight on glossy skins.
  void shade_colour(std::size_t i, const Eigen::Vector3d& to_eye, const Hit& hit, const World& occluders) {
    const Material& mat = world_.materials().get(hit.material);
    const Eigen::Vector3d to_light = (P.light_position_m - hit.point).normalized();
    double diffuse = std::max(0.0, hit.normal.dot(to_light));
    if (diffuse > 0 && P.shadows && occluders.occluded(hit.point + 1e-5 * hit.normal, P.light_position_m)) diffuse = 0;
    Eigen::Vector3d c = mat.rgb * (P.ambient + P.light_intensity * diffuse);
    if (diffuse > 0) {
      if (const Gloss* g = gloss_by_material[static_cast<std::size_t>(hit.material)]) {
        const double nh = std::max(0.0, hit.normal.dot((to_light + to_eye).normalized()));
        c += Eigen::Vector3d::Constant(g->strength * std::pow(nh, g->exponent));
      }
    }
    linear_rgb[i] = c.cast<float>();
  }

  void render_tile(int u0, int v0) {
    const int u1 = std::min(W, u0 + kTile), v1 = std::min(H, v0 + kTile);
    const SubWorld primary(world_, objects_in_cone(u0, v0, u1, v1));
    for (int v = v0; v < v1; ++v) {
      for (int u = u0; u < u1; ++u) {
        const std::size_t t = tile_slot(u, v, u0, v0);
        const auto hit = primary.world.raycast({eye, R * K.ray(u, v)});
        hit_ok_[t] = hit.has_value();
        if (hit) hits_[t] = *hit;
      }
    }
    group_hits_by_object(u1 - u0, v1 - v0);
    for (const auto& [object, obox] : seen_) {
      const SubWorld shadow(world_, objects_near_shadow_rays(obox));
      for (int v = v0; v < v1; ++v) {
        for (int u = u0; u < u1; ++u) {
          const std::size_t t = tile_slot(u, v, u0, v0);
          if (!hit_ok_[t] || hits_[t].object != object) continue;
          const Eigen::Vector3d dir_c = K.ray(u, v);
          const Ray ray{eye, R * dir_c};
          shade(pixel(u, v), ray, dir_c.z(), hits_[t], primary.original[static_cast<std::size_t>(object)],
                shadow.world);
        }
      }
    }
    for (int v = v0; v < v1; ++v)
      for (int u = u0; u < u1; ++u)
        if (!hit_ok_[tile_slot(u, v, u0, v0)]) linear_rgb[pixel(u, v)] = P.background_rgb.cast<float>();
  }

  // The objects whose bounding spheres meet the cone of the tile's rays.
  std::vector<ObjectId> objects_in_cone(int u0, int v0, int u1, int v1) const {
    const Eigen::Vector3d axis = R * K.ray(0.5 * (u0 + u1 - 1), 0.5 * (v0 + v1 - 1));
    double half = 0.0;
    for (const auto& [cu, cv] : {std::pair{u0, v0}, {u1 - 1, v0}, {u0, v1 - 1}, {u1 - 1, v1 - 1}})
      half = std::max(half, std::acos(std::clamp(axis.dot(R * K.ray(cu, cv)), -1.0, 1.0)));
    half += 1e-6;
    std::vector<ObjectId> ids;
    for (std::size_t k = 0; k < bounds_.size(); ++k)
      if (sphere_meets_cone(bounds_[k], eye, axis, half)) ids.push_back(static_cast<ObjectId>(k));
    return ids;
  }

  // Shadow rays go per object seen in the tile: the hits on one surface are
  // close together, so the segments to the lamp and projector stay in a
  // thin capsule. The objects seen, in order of first hit, with their hits' box.
  void group_hits_by_object(int tile_w, int tile_h) {
    seen_.clear();
    for (int t = 0; t < tile_w * tile_h; ++t) {
      const int tu = t % tile_w, tv = t / tile_w;
      const std::size_t k = static_cast<std::size_t>(tv * kTile + tu);
      if (!hit_ok_[k]) continue;
      const ObjectId o = hits_[k].object;
      auto it = std::find_if(seen_.begin(), seen_.end(), [&](const auto& e) { return e.first == o; });
      if (it == seen_.end()) {
        seen_.emplace_back(o, Eigen::AlignedBox3d());
        it = seen_.end() - 1;
      }
      it->second.extend(hits_[k].point);
    }
  }

  // The objects near the segments from a box of hits to the lamp and the projector.
  std::vector<ObjectId> objects_near_shadow_rays(const Eigen::AlignedBox3d& obox) const {
    std::vector<ObjectId> ids;
    const Eigen::Vector3d c = obox.center();
    const double r = 0.5 * obox.diagonal().norm() + 1e-6;
    for (std::size_t k = 0; k < bounds_.size(); ++k)
      if ((P.shadows && sphere_meets_capsule(bounds_[k], c, P.light_position_m, r)) ||
          (P.projector_shadow && sphere_meets_capsule(bounds_[k], c, projector, r)))
        ids.push_back(static_cast<ObjectId>(k));
    return ids;
  }

  const RgbdCameraParams& P;
  const PinholeIntrinsics& K;
  const World& world_;
  RgbdFrame& f;
  const int W, H;
  const std::size_t N;
  const Eigen::Matrix3d R;
  const Eigen::Vector3d eye, projector;
  const double cos_graze_start, cos_graze_end;
  const std::uint64_t frame_index_, key_dropout, key_white, key_colour, key_graze;
  // Which surfaces the pattern can return depth from, before noise.
  std::vector<float> z_true;
  std::vector<std::uint8_t> has_depth;
  std::vector<Eigen::Vector3f> linear_rgb;
  std::vector<const Gloss*> gloss_by_material;
  // Tiled casting's scratch.
  std::vector<Bound> bounds_;
  std::vector<Hit> hits_;
  std::vector<std::uint8_t> hit_ok_;
  std::vector<std::pair<ObjectId, Eigen::AlignedBox3d>> seen_;
};

}  // namespace

RgbdFrame RgbdCamera::render(const World& world, const Eigen::Isometry3d& T_world_camera,
                             std::uint64_t frame_index) const {
  RgbdFrame f;
  FrameRenderer r(params_, world, T_world_camera, frame_index, f);
  if (params_.tile_culling) {
    r.cast_tiled();
  } else {
    r.cast_all();
  }
  r.measure_depth(r.silhouette_edges());
  r.encode_colour();
  return f;
}

Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, const Eigen::Vector3d& up) {
  const Eigen::Vector3d z = (target - eye).normalized();
  Eigen::Vector3d x = z.cross(up);
  if (x.norm() < 1e-9) x = z.unitOrthogonal();  // looking straight up or down
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);  // points down on screen when up is up
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = y;
  T.linear().col(2) = z;
  T.translation() = eye;
  return T;
}

double srgb_encode(double linear) {
  const double l = std::clamp(linear, 0.0, 1.0);
  const double s = l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(l, 1.0 / 2.4) - 0.055;
  return 255.0 * s;
}

}  // namespace tinyline::sim
