// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/hsi_filter.hpp"

#include "tomato_reasoning/param_tables.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace tinyline::tomato_reasoning {

namespace {
// PCL's PackedHSIComparison: the hue vector and integer saturation/intensity.
struct HueVector {
  double hx, hy;
};
HueVector hue_vector(const Rgb& c) {
  const int r = c[0], g = c[1], b = c[2];
  return {(2.0 * r - g - b) / 4.0, (g - b) * 111.0 / 255.0};
}
int intensity(const Rgb& c) { return (c[0] + c[1] + c[2]) / 3; }
int saturation(const Rgb& c, int i) {
  const int m = std::min({c[0], c[1], c[2]});
  return i == 0 ? 0 : 255 - (m * 255) / i;
}
}  // namespace

common::Status validate(const HsiFilterParams& p) {
  if (common::Status s = common::within_table(p); !s.ok()) return s;
  if (!(p.h_min_deg <= p.h_max_deg))
    return common::Status::invalid("hue range must satisfy h_min_deg <= h_max_deg (got [" +
                                   std::to_string(p.h_min_deg) + ", " + std::to_string(p.h_max_deg) + "])");
  if (p.s_min > p.s_max) return common::Status::invalid("saturation range must satisfy s_min <= s_max");
  if (p.i_min > p.i_max) return common::Status::invalid("intensity range must satisfy i_min <= i_max");
  return {};
}

Hsi to_hsi(const Rgb& c) {
  const HueVector h = hue_vector(c);
  const int i = intensity(c);
  return {std::atan2(h.hy, h.hx) * 180.0 / M_PI, saturation(c, i), i};
}

HsiFilter::HsiFilter(const HsiFilterParams& params) : params_(params) {
  if (const common::Status why = validate(params); !why.ok()) throw std::invalid_argument("HSI filter: " + why.message);
  const double a = params.h_min_deg * M_PI / 180.0, b = params.h_max_deg * M_PI / 180.0;
  cos_min_ = std::cos(a);
  sin_min_ = std::sin(a);
  cos_max_ = std::cos(b);
  sin_max_ = std::sin(b);
  wide_ = params.h_max_deg - params.h_min_deg > 180.0;
}

bool HsiFilter::passes(const Rgb& c) const {
  const int i = intensity(c);
  if (i < params_.i_min || i > params_.i_max) return false;
  const int s = saturation(c, i);
  if (s < params_.s_min || s > params_.s_max) return false;
  const HueVector h = hue_vector(c);
  if (h.hx == 0.0 && h.hy == 0.0) return params_.h_min_deg <= 0.0 && params_.h_max_deg >= 0.0;  // atan2(0, 0) = 0
  // Inside the wedge from h_min to h_max (counter-clockwise): to the left of
  // the h_min ray and to the right of the h_max ray. A range wider than a
  // half turn is everything outside the opposite wedge.
  const double left_of_min = cos_min_ * h.hy - sin_min_ * h.hx;
  const double right_of_max = h.hx * sin_max_ - h.hy * cos_max_;
  if (!wide_) return left_of_min >= 0.0 && right_of_max >= 0.0;
  return left_of_min >= 0.0 || right_of_max >= 0.0;
}

HsiFilterResult filter_hsi(const CloudView& cloud, const HsiFilterParams& params) {
  HsiFilterResult r;
  if (const common::Status why = validate(params); !why.ok()) {
    r.status = common::Status::invalid("bad HSI parameters: " + why.message);
    return r;
  }
  if (const common::Status why = check_view(cloud); !why.ok()) {
    r.status = common::Status::invalid("malformed cloud: " + why.message);
    return r;
  }
  if (cloud.empty()) {
    r.status = common::Status::not_found("empty cloud");
    return r;
  }
  const HsiFilter f(params);
  r.indices.reserve(cloud.size() / 8);
  for (std::size_t k = 0; k < cloud.size(); ++k) {
    if (!cloud.finite(k)) continue;
    ++r.finite;
    if (f.passes(cloud.colour(k))) r.indices.push_back(static_cast<int>(k));
  }
  if (r.finite == 0) {
    r.status = common::Status::not_found("no point of the cloud has depth (" + std::to_string(cloud.size()) +
                                         " points, all NaN)");
  } else if (r.indices.empty()) {
    r.status = common::Status::not_found("no point passes the HSI filter (" + std::to_string(r.finite) +
                                         " points with depth, none red)");
  }
  return r;
}

}  // namespace tinyline::tomato_reasoning
