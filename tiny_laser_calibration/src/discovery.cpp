// SPDX-License-Identifier: Apache-2.0
// The residual loop: grouped cross-validation of candidate terms on top of the
// declared model (or of a given model's residuals), a justified acceptance
// margin, and before/after errors on held-out groups.
#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <numeric>
#include <random>

#include <fmt/format.h>

#include <tiny_laser_calibration/discovery.hpp>

#include "discovery_internal.hpp"

namespace tinyline::tiny_laser_calibration {

std::string_view to_string(GroupBy g) {
  switch (g) {
    case GroupBy::kAuto: return "auto";
    case GroupBy::kTargetDistance: return "target_distance";
    case GroupBy::kFrame: return "frame";
  }
  return "?";
}

double normal_upper_quantile(double p) {
  // Bisection on the survival function: plenty fast for a few calls per round.
  if (!(p > 0.0)) return std::numeric_limits<double>::infinity();
  if (p >= 1.0) return -std::numeric_limits<double>::infinity();
  double lo = -40.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    const double sf = 0.5 * std::erfc(mid / std::sqrt(2.0));
    (sf > p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
using detail::CvData;
using detail::CvTerm;
using detail::Entries;
using detail::NormalEquations;
using detail::quantile_knots;

// ------------------------------------------------------------------ split

struct Split {
  GroupBy grouping = GroupBy::kAuto;
  std::vector<int> group;  // per dataset row
  std::size_t groups = 0;
  std::vector<bool> holdout;  // per group
  std::vector<int> fold;      // per group: -1 always in training
  std::size_t holdout_groups = 0;
  std::string problem;
};

std::size_t count_groups(const std::vector<int>& g, const std::vector<bool>& valid) {
  std::vector<int> seen;
  for (std::size_t i = 0; i < g.size(); ++i) {
    if (valid[i]) seen.push_back(g[i]);
  }
  std::sort(seen.begin(), seen.end());
  return static_cast<std::size_t>(std::unique(seen.begin(), seen.end()) - seen.begin());
}

Split make_split(const CalibrationDataset& data, const DiscoveryParams& p, const std::vector<bool>& valid) {
  Split s;
  const std::size_t need = static_cast<std::size_t>(3 * std::max(p.folds, 2));
  GroupBy g = p.group_by;
  std::vector<int> target, frames;
  if (g != GroupBy::kFrame) target = target_distance_groups(data);
  if (g == GroupBy::kAuto) {
    g = count_groups(target, valid) >= need ? GroupBy::kTargetDistance : GroupBy::kFrame;
  }
  s.grouping = g;
  s.group = g == GroupBy::kTargetDistance ? target : frame_ids(data);
  // Dense ids over valid rows, in the original order (target groups: increasing distance).
  std::vector<int> ids;
  for (std::size_t i = 0; i < s.group.size(); ++i) {
    if (valid[i]) ids.push_back(s.group[i]);
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  for (std::size_t i = 0; i < s.group.size(); ++i) {
    const auto it = std::lower_bound(ids.begin(), ids.end(), s.group[i]);
    s.group[i] = (it != ids.end() && *it == s.group[i]) ? static_cast<int>(it - ids.begin()) : -1;
  }
  s.groups = ids.size();
  if (s.groups < need) {
    s.problem = fmt::format(
        "only {} {} groups among the valid read-outs: {}-fold cross-validation with a held-out "
        "share needs at least {}",
        s.groups, to_string(g), p.folds, need);
    return s;
  }
  std::mt19937_64 rng(p.seed);
  std::vector<int> order(s.groups);
  std::iota(order.begin(), order.end(), 0);
  s.holdout.assign(s.groups, false);
  s.fold.assign(s.groups, -1);
  // The nearest and farthest targets always train, so nothing asks the polynomial to extrapolate.
  std::vector<int> movable;
  for (int id : order) {
    const bool extreme = g == GroupBy::kTargetDistance && (id == 0 || id == static_cast<int>(s.groups) - 1);
    if (!extreme) movable.push_back(id);
  }
  std::shuffle(movable.begin(), movable.end(), rng);
  s.holdout_groups = std::max<std::size_t>(
      1, static_cast<std::size_t>(std::lround(p.holdout_fraction * static_cast<double>(s.groups))));
  s.holdout_groups = std::min(s.holdout_groups, movable.size() / 2);
  for (std::size_t k = 0; k < movable.size(); ++k) {
    const auto id = static_cast<std::size_t>(movable[k]);
    if (k < s.holdout_groups) {
      s.holdout[id] = true;
    } else {
      s.fold[id] = static_cast<int>((k - s.holdout_groups) % static_cast<std::size_t>(p.folds));
    }
  }
  return s;
}

// ------------------------------------------------------------------ cross-validation

struct CvResult {
  double sse = 0.0;
  std::size_t n = 0;
  std::vector<double> group_sse;
  [[nodiscard]] double rmse() const { return n ? std::sqrt(sse / static_cast<double>(n)) : kNaN; }
};

std::size_t columns(const CvData& d, const std::vector<const CvTerm*>& terms, std::vector<std::size_t>& offsets) {
  std::size_t cols = d.base_cols;
  offsets.clear();
  for (const auto* t : terms) {
    offsets.push_back(cols);
    cols += t->ncols;
  }
  return cols;
}

void row_entries(const CvData& d, const std::vector<const CvTerm*>& terms, const std::vector<std::size_t>& offsets,
                 std::size_t i, Entries& out) {
  out = d.base[i];
  for (std::size_t k = 0; k < terms.size(); ++k) {
    const auto* e = terms[k]->cols.row(i);
    for (std::size_t j = 0; j < terms[k]->cols.size(i); ++j) out.emplace_back(offsets[k] + e[j].first, e[j].second);
  }
}

Eigen::VectorXd ridge_vector(const CvData& d, std::size_t cols, double term_ridge) {
  Eigen::VectorXd r = Eigen::VectorXd::Constant(static_cast<Eigen::Index>(cols), term_ridge);
  for (std::size_t c = 0; c < d.base_cols; ++c) r[static_cast<Eigen::Index>(c)] = 1e-9;
  return r;
}

detail::SparseRows design(const CvData& d, const std::vector<const CvTerm*>& terms,
                          const std::vector<std::size_t>& offsets) {
  detail::SparseRows rows;
  rows.entries.reserve(d.y.size() * (d.base.empty() ? 1 : d.base.front().size() + 2 * terms.size()));
  Entries e;
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    row_entries(d, terms, offsets, i, e);
    rows.push(e);
  }
  return rows;
}

CvResult cross_validate(const CvData& d, const std::vector<const CvTerm*>& terms, double term_ridge) {
  std::vector<std::size_t> offsets;
  const std::size_t cols = columns(d, terms, offsets);
  const detail::SparseRows x = design(d, terms, offsets);
  std::vector<NormalEquations> per_fold(static_cast<std::size_t>(d.folds), NormalEquations(cols));
  NormalEquations total(cols);
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    if (d.fold[i] == -2) continue;
    auto& ne = d.fold[i] >= 0 ? per_fold[static_cast<std::size_t>(d.fold[i])] : total;
    ne.add(x.row(i), x.size(i), d.y[i], d.w[i]);
  }
  for (const auto& f : per_fold) total += f;
  const Eigen::VectorXd ridge = ridge_vector(d, cols, term_ridge);
  std::vector<Eigen::VectorXd> coef;
  for (const auto& f : per_fold) {
    NormalEquations train = total;
    train -= f;
    coef.push_back(train.solve(ridge));
  }
  CvResult res;
  res.group_sse.assign(d.groups, 0.0);
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    if (d.fold[i] < 0) continue;
    const double r = d.y[i] - detail::dot(x.row(i), x.size(i), coef[static_cast<std::size_t>(d.fold[i])].data());
    res.sse += r * r;
    res.group_sse[static_cast<std::size_t>(d.group[i])] += r * r;
    ++res.n;
  }
  return res;
}

// Fit on every non-held-out row; predictions for all rows.
std::vector<double> fit_and_predict(const CvData& d, const std::vector<const CvTerm*>& terms, double term_ridge) {
  std::vector<std::size_t> offsets;
  const std::size_t cols = columns(d, terms, offsets);
  const detail::SparseRows x = design(d, terms, offsets);
  NormalEquations ne(cols);
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    if (d.fold[i] != -2) ne.add(x.row(i), x.size(i), d.y[i], d.w[i]);
  }
  const Eigen::VectorXd c = ne.solve(ridge_vector(d, cols, term_ridge));
  std::vector<double> pred(d.y.size());
  for (std::size_t i = 0; i < d.y.size(); ++i) pred[i] = detail::dot(x.row(i), x.size(i), c.data());
  return pred;
}

// ------------------------------------------------------------------ candidates

}  // namespace

std::vector<double> detail::quantile_knots(std::vector<double> v, int n) {
  std::sort(v.begin(), v.end());
  std::vector<double> k;
  for (int i = 0; i < n; ++i) {
    const double q = static_cast<double>(i) / (n - 1);
    const double pos = q * static_cast<double>(v.size() - 1);
    const auto lo = static_cast<std::size_t>(std::floor(pos));
    const auto hi = std::min(lo + 1, v.size() - 1);
    const double val = v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
    if (k.empty() || val > k.back() + 1e-12 * std::max(1.0, std::abs(val))) k.push_back(val);
  }
  return k;
}

namespace {

struct CovariateInfo {
  std::string name;
  Covariate kind = Covariate::kExtra;
  int data_extra = -1;
};

std::vector<CovariateInfo> candidate_covariates(const CalibrationDataset& data, const DiscoveryParams& p) {
  std::vector<CovariateInfo> out;
  auto excluded = [&](const std::string& n) {
    return std::find(p.exclude.begin(), p.exclude.end(), n) != p.exclude.end();
  };
  for (Covariate c : builtin_covariates()) {
    const std::string n(covariate_name(c));
    if (!excluded(n)) out.push_back({n, c, -1});
  }
  for (std::size_t k = 0; k < data.extra_names.size(); ++k) {
    const auto& n = data.extra_names[k];
    // A column may not shadow a built-in name; `session` names a warm-up, not a covariate.
    if (excluded(n) || covariate_from_name(n) != Covariate::kExtra || n == "session") continue;
    out.push_back({n, Covariate::kExtra, static_cast<int>(k)});
  }
  return out;
}

// The covariate on every CV row; `fitted` gets its values on the rows fitted on.
CvTerm covariate_on_rows(const CalibrationDataset& data, const CvData& d, const CovariateInfo& cov,
                         std::vector<double>& fitted, std::size_t& finite) {
  CvTerm base;
  base.term.covariate = cov.name;
  base.term.kind = cov.kind;
  base.data_extra = cov.data_extra;
  base.z.resize(d.y.size());
  finite = 0;
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    base.z[i] = detail::term_covariate(data, d.row[i], base.term, cov.data_extra, d.x[i], d.declared[i], *d.reference);
    if (std::isfinite(base.z[i])) {
      ++finite;
      if (d.fold[i] != -2) fitted.push_back(base.z[i]);
    }
  }
  return base;
}

// Albedo and reflectance both divide the light by the declared distance
// squared, so on one surface their only variation is the distance error
// itself: a term on them would range by intensity and fail on the next
// surface. Try them only when the data holds surfaces of clearly different
// albedo (90th/10th percentile >= min_albedo_spread, beyond what a distance
// error of several percent could fake).
bool albedo_spread_enough(const CalibrationDataset& data, const CvData& d, const CovariateInfo& cov,
                          const DiscoveryParams& p, std::vector<std::string>& notes) {
  std::vector<double> albedo;
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    if (d.fold[i] == -2) continue;
    const double a = d.reference->albedo(data.readouts[d.row[i]], d.declared[i]);
    if (std::isfinite(a)) albedo.push_back(a);
  }
  if (albedo.size() < 10) return false;
  std::sort(albedo.begin(), albedo.end());
  const double p10 = albedo[albedo.size() / 10], p90 = albedo[albedo.size() * 9 / 10];
  if (p10 > 0.0 && p90 / p10 >= p.min_albedo_spread) return true;
  if (cov.kind == Covariate::kAlbedo) {
    notes.push_back(
        fmt::format("albedo spans {:.2f}x (90th/10th percentile < {:.2f}): one kind of surface, so albedo "
                    "and reflectance are not tried",
                    p10 > 0.0 ? p90 / p10 : 0.0, p.min_albedo_spread));
  }
  return false;
}

// g(z) * (a + b - median) / IQR-scale, knots at quantiles of z.
void add_interaction_form(const CvData& d, const CvTerm& base, const std::vector<double>& fitted,
                          const std::vector<double>& distinct, const DiscoveryParams& p, std::vector<CvTerm>& out) {
  std::vector<double> amp;
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    if (d.fold[i] != -2) amp.push_back(d.amplitude[i]);
  }
  const auto q = quantile_knots(amp, 5);  // quartiles
  if (!(q.size() == 5 && q[3] > q[1])) return;
  CvTerm t = base;
  t.term.form = TermForm::kAmplitudeInteraction;
  t.term.knots = distinct.size() <= static_cast<std::size_t>(p.interaction_knots)
                     ? distinct
                     : quantile_knots(fitted, p.interaction_knots);
  t.term.amplitude_reference = q[2];
  t.term.amplitude_scale = (q[3] - q[1]) / 1.349;  // IQR as an SD
  if (t.term.knots.size() >= 2) out.push_back(std::move(t));
}

// Builds every applicable form of one covariate on the CV rows.
void build_forms(const CalibrationDataset& data, const CvData& d, const CovariateInfo& cov, const DiscoveryParams& p,
                 std::vector<CvTerm>& out, std::vector<std::string>& notes) {
  const std::size_t first_new = out.size();
  std::vector<double> fitted;  // values on fitting rows
  std::size_t finite = 0;
  const CvTerm base = covariate_on_rows(data, d, cov, fitted, finite);
  if (finite < d.y.size() * 9 / 10 || fitted.size() < 10) {
    notes.push_back(fmt::format("covariate '{}' is missing on {} of {} read-outs: not tried", cov.name,
                                d.y.size() - finite, d.y.size()));
    return;
  }
  const bool albedo_like = cov.kind == Covariate::kAlbedo || cov.kind == Covariate::kReflectance;
  if (albedo_like && !albedo_spread_enough(data, d, cov, p, notes)) return;
  std::vector<double> distinct = fitted;
  std::sort(distinct.begin(), distinct.end());
  distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
  if (distinct.size() < 2) return;  // constant: nothing to explain with it
  const bool integer = std::all_of(distinct.begin(), distinct.end(), [](double v) { return v == std::round(v); });

  if (distinct.size() >= 3) {
    CvTerm t = base;
    t.term.form = TermForm::kSmooth;
    t.term.knots =
        distinct.size() <= static_cast<std::size_t>(p.smooth_knots) ? distinct : quantile_knots(fitted, p.smooth_knots);
    if (t.term.knots.size() >= 3) out.push_back(std::move(t));
  }
  if (integer && distinct.size() <= static_cast<std::size_t>(p.table_max_values)) {
    CvTerm t = base;
    t.term.form = TermForm::kTable;
    for (double v : distinct) t.term.keys.push_back(std::lround(v));
    out.push_back(std::move(t));
  }
  if (cov.kind != Covariate::kAmplitude) add_interaction_form(d, base, fitted, distinct, p, out);
  for (std::size_t k = first_new; k < out.size(); ++k) detail::materialise(out[k], d, data);
}

struct Paired {
  double z = 0.0;
  double gain = 0.0;
};

// z of a paired comparison: mean over groups / its standard error.
double paired_z(const std::vector<double>& diff) {
  const double n = static_cast<double>(diff.size());
  if (n < 2) return 0.0;
  const double mean = std::accumulate(diff.begin(), diff.end(), 0.0) / n;
  double var = 0.0;
  for (double v : diff) var += (v - mean) * (v - mean);
  var /= (n - 1.0);
  const double se = std::sqrt(var / n);
  return se > 0.0 ? mean / se : (mean > 0.0 ? std::numeric_limits<double>::infinity() : 0.0);
}

// Two paired statistics over the cross-validation groups, the larger counts
// (the round's Bonferroni threshold covers both: kStatistics per candidate):
//  - per group the log ratio of its squared error without and with the term:
//    every group weighs the same whatever its size or noise (far targets are
//    noisier), and a group made k times worse weighs as much as one made k
//    times better;
//  - per group the squared error the term removes: sensitive to an effect that
//    lives in some groups only (a dark material seen at a few rail positions),
//    which the equal-weight statistic dilutes.
constexpr int kStatistics = 2;

Paired compare(const CvResult& current, const CvResult& candidate) {
  Paired out;
  std::vector<double> log_ratio, removed;
  for (std::size_t g = 0; g < current.group_sse.size(); ++g) {
    if (current.group_sse[g] > 0.0 && candidate.group_sse[g] > 0.0) {
      log_ratio.push_back(std::log(current.group_sse[g] / candidate.group_sse[g]));
    }
    removed.push_back(current.group_sse[g] - candidate.group_sse[g]);
  }
  out.z = std::max(paired_z(log_ratio), paired_z(removed));
  out.gain = current.sse > 0.0 ? (current.sse - candidate.sse) / current.sse : 0.0;
  return out;
}

// ------------------------------------------------------------------ the loop

// What one round works on: the rows with their fixed columns, and the terms
// accepted so far evaluated on those rows.
struct RoundInput {
  CvData d;
  std::vector<CvTerm> accepted;
};
using Prepare = std::function<RoundInput(const std::vector<CalibrationTerm>& accepted)>;

CvTerm evaluate_term(const CalibrationDataset& data, const CvData& d, const CalibrationTerm& structure) {
  CvTerm t;
  t.term = structure;
  t.term.kind = covariate_from_name(structure.covariate);
  t.data_extra = t.term.kind == Covariate::kExtra ? data.extra_index(structure.covariate) : -1;
  t.z.resize(d.y.size());
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    t.z[i] = detail::term_covariate(data, d.row[i], t.term, t.data_extra, d.x[i], d.declared[i], *d.reference);
  }
  detail::materialise(t, d, data);
  return t;
}

struct LoopOutcome {
  std::vector<CalibrationTerm> accepted;
  std::vector<DiscoveredEffect> effects;
  std::vector<std::vector<CandidateScore>> rounds;
  std::vector<std::string> candidates;
  double z_threshold = 0.0;
};

// Every candidate of a round: the distance forms of each covariate not used
// yet, and the hypotheses that act on the charges.
std::vector<CvTerm> round_candidates(const CalibrationDataset& data, const RoundInput& in,
                                     const std::vector<CovariateInfo>& covariates, const std::vector<std::string>& used,
                                     const std::vector<const CvTerm*>& current_terms, const DiscoveryParams& p,
                                     bool first_round, LoopOutcome& o, std::vector<std::string>& notes) {
  std::vector<CvTerm> forms;
  for (const auto& cov : covariates) {
    if (std::find(used.begin(), used.end(), cov.name) != used.end()) continue;  // one term per covariate
    const std::size_t before = forms.size();
    std::vector<std::string> form_notes;
    build_forms(data, in.d, cov, p, forms, form_notes);
    if (first_round) {
      notes.insert(notes.end(), form_notes.begin(), form_notes.end());
      if (forms.size() > before) o.candidates.push_back(cov.name);
    }
  }
  const auto pred = fit_and_predict(in.d, current_terms, p.declared.term_ridge);
  std::vector<double> residual(pred.size());
  for (std::size_t i = 0; i < pred.size(); ++i) residual[i] = in.d.y[i] - pred[i];
  std::vector<std::string> charge_notes;
  const std::size_t before = forms.size();
  detail::build_charge_forms(data, in.d, p, residual, used, forms, charge_notes);
  if (first_round) {
    notes.insert(notes.end(), charge_notes.begin(), charge_notes.end());
    for (std::size_t k = before; k < forms.size(); ++k) {
      const auto& n = forms[k].term.covariate;
      if (std::find(o.candidates.begin(), o.candidates.end(), n) == o.candidates.end()) o.candidates.push_back(n);
    }
  }
  return forms;
}

struct RoundScores {
  std::vector<CandidateScore> scores;
  int best = -1;
  CvResult best_res;
  Paired best_cmp;
};

RoundScores score_round(const RoundInput& in, const std::vector<CvTerm>& forms,
                        const std::vector<const CvTerm*>& current_terms, const CvResult& current, double z_thr,
                        const DiscoveryParams& p) {
  RoundScores out;
  for (std::size_t k = 0; k < forms.size(); ++k) {
    auto terms = current_terms;
    terms.push_back(&forms[k]);
    const CvResult r = cross_validate(in.d, terms, p.declared.term_ridge);
    const Paired cmp = compare(current, r);
    CandidateScore sc;
    sc.covariate = forms[k].term.covariate;
    sc.form = forms[k].term.form;
    sc.cv_rmse_m = r.rmse();
    sc.gain = cmp.gain;
    sc.z = cmp.z;
    sc.passes = cmp.z > z_thr && cmp.gain > p.min_relative_gain;
    out.scores.push_back(sc);
    if (sc.passes && (out.best < 0 || cmp.gain > out.best_cmp.gain)) {
      out.best = static_cast<int>(k);
      out.best_res = r;
      out.best_cmp = cmp;
    }
  }
  std::sort(out.scores.begin(), out.scores.end(), [](const auto& a, const auto& b) { return a.gain > b.gain; });
  return out;
}

// The z a candidate must beat: one-sided Bonferroni over every test of the
// round (kStatistics per candidate, a candidate chosen from the data counting
// as every one it was chosen from). The loop stops at the first round where
// nothing passes, so on effect-free data only round 0 can name anything and
// the chance that it does stays under alpha.
double family_threshold(const std::vector<CvTerm>& forms, const DiscoveryParams& p) {
  double looks = 0.0;
  for (const auto& f : forms) looks += f.looks;
  return normal_upper_quantile(p.alpha / (kStatistics * looks));
}

LoopOutcome run_loop(const CalibrationDataset& data, const Prepare& prepare, const DiscoveryParams& p,
                     std::vector<std::string>& notes) {
  LoopOutcome o;
  const auto covariates = candidate_covariates(data, p);
  std::vector<std::string> used;
  for (int round = 0; round <= p.max_terms; ++round) {
    // Each round starts from the current model refitted with every accepted term,
    // so a declared parameter that an effect had bent is straightened first.
    RoundInput in = prepare(o.accepted);
    std::vector<const CvTerm*> current_terms;
    for (const auto& t : in.accepted) current_terms.push_back(&t);
    const CvResult current = cross_validate(in.d, current_terms, p.declared.term_ridge);
    if (round == p.max_terms) break;
    const std::vector<CvTerm> forms =
        round_candidates(data, in, covariates, used, current_terms, p, round == 0, o, notes);
    if (forms.empty()) break;
    const double z_thr = family_threshold(forms, p);
    if (round == 0) o.z_threshold = z_thr;
    RoundScores scored = score_round(in, forms, current_terms, current, z_thr, p);
    o.rounds.push_back(std::move(scored.scores));
    if (scored.best < 0) break;
    const auto& chosen = forms[static_cast<std::size_t>(scored.best)];
    DiscoveredEffect e;
    e.covariate = chosen.term.covariate;
    e.form = chosen.term.form;
    e.cv_rmse_before_m = current.rmse();
    e.cv_rmse_after_m = scored.best_res.rmse();
    e.gain = scored.best_cmp.gain;
    e.z = scored.best_cmp.z;
    o.effects.push_back(e);
    o.accepted.push_back(chosen.term);
    used.push_back(chosen.term.covariate);
  }
  return o;
}

// A term stays only if the held-out squared error drops by at least half the
// cross-validation margin: the held-out groups confirm the gain at its scale.
bool confirmed(double before_rmse, double after_rmse, const DiscoveryParams& p) {
  if (!std::isfinite(after_rmse)) return false;
  return after_rmse * after_rmse < (1.0 - 0.5 * p.min_relative_gain) * before_rmse * before_rmse;
}

std::vector<std::size_t> rows_where(const Split& s, const std::vector<bool>& valid, bool holdout) {
  std::vector<std::size_t> rows;
  for (std::size_t i = 0; i < s.group.size(); ++i) {
    if (!valid[i] || s.group[i] < 0) continue;
    if (s.holdout[static_cast<std::size_t>(s.group[i])] == holdout) rows.push_back(i);
  }
  return rows;
}

void dense_cv_groups(CvData& d, const Split& s) {
  std::vector<int> map(s.groups, -1);
  int next = 0;
  d.group.resize(d.row.size());
  for (std::size_t i = 0; i < d.row.size(); ++i) {
    const int g = s.group[d.row[i]];
    if (d.fold[i] < 0) {
      d.group[i] = -1;
      continue;
    }
    if (map[static_cast<std::size_t>(g)] < 0) map[static_cast<std::size_t>(g)] = next++;
    d.group[i] = map[static_cast<std::size_t>(g)];
  }
  d.groups = static_cast<std::size_t>(next);
}

// Valid read-outs under the declared validity rule; n_valid counts them.
std::vector<bool> valid_rows(const CalibrationDataset& data, const ValidityRule& rule, std::size_t& n_valid) {
  std::vector<bool> valid(data.size());
  n_valid = 0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    valid[i] = rule.check(data.readouts[i]) == ValidityRule::Verdict::kValid;
    n_valid += valid[i] ? 1 : 0;
  }
  return valid;
}

// Whether surfaces of a `material` column share target distances (at least half
// of the distances seen on two or more): only then is a charge per pulse's level
// told apart from the distance, which on one surface the light per pulse encodes.
bool surfaces_share_distances(const CalibrationDataset& data, const std::vector<bool>& valid) {
  const std::vector<int> target = target_distance_groups(data);
  std::vector<std::pair<int, int>> seen;  // (target group, material)
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (valid[i] && target[i] >= 0 && data.material[i] >= 0) seen.emplace_back(target[i], data.material[i]);
  }
  std::sort(seen.begin(), seen.end());
  seen.erase(std::unique(seen.begin(), seen.end()), seen.end());
  std::size_t groups = 0, shared = 0;
  for (std::size_t k = 0; k < seen.size();) {
    std::size_t e = k;
    while (e < seen.size() && seen[e].first == seen[k].first) ++e;
    ++groups;
    shared += e - k >= 2 ? 1 : 0;
    k = e;
  }
  return groups > 0 && 2 * shared >= groups;
}

// The split into training and held-out groups, recorded in the result; false
// (with the reason) when there are too few groups.
bool split_into(DiscoveryResult& res, const CalibrationDataset& data, const DiscoveryParams& p,
                const std::vector<bool>& valid, Split& split) {
  split = make_split(data, p, valid);
  res.grouping = split.grouping;
  res.groups = split.groups;
  res.holdout_groups = split.holdout_groups;
  if (!split.problem.empty()) {
    res.status = common::Status::invalid(split.problem);
    return false;
  }
  res.train_rows = rows_where(split, valid, false);
  res.holdout_rows = rows_where(split, valid, true);
  return true;
}

// The CV rows of a fitted engine: its declared columns, truth, weights, X and folds.
CvData cv_data_from_engine(const CalibrationDataset& data, const detail::FitEngine& engine, const Split& split,
                           int folds) {
  CvData d;
  d.folds = folds;
  d.base_cols = engine.declared_columns();
  d.reference = &engine.amplitude_reference();
  const auto& kept = engine.rows();
  for (std::size_t i = 0; i < kept.size(); ++i) {
    Entries base;
    engine.declared_entries(i, base);
    if (base.empty()) continue;
    const Readout& r = data.readouts[kept[i]];
    d.row.push_back(kept[i]);
    d.base.push_back(std::move(base));
    d.y.push_back(engine.y(i));
    d.w.push_back(engine.weight(i));
    d.x.push_back(engine.x(i));
    d.declared.push_back(engine.declared_m(i));
    d.amplitude.push_back(r.a + r.b);
    d.sens.push_back(engine.charge_sensitivity(i));
    d.fold.push_back(split.fold[static_cast<std::size_t>(split.group[kept[i]])]);
  }
  dense_cv_groups(d, split);
  return d;
}

// Held-out errors, one accepted term at a time, each a refit of the whole
// model on the training groups; a term that does not lower the held-out error
// is dropped. Returns the terms kept.
std::vector<CalibrationTerm> confirm_on_holdout(DiscoveryResult& res, const CalibrationDataset& data,
                                                const DiscoveryParams& p, const LoopOutcome& loop) {
  const ErrorStats before = evaluate_model(res.train_before, data, res.holdout_rows, p.declared.selection);
  res.rmse_before_m = before.rmse_m;
  if (before.out_of_range > 0) {
    res.notes.push_back(
        fmt::format("{} held-out read-outs fall outside the ratio range of the training fit", before.out_of_range));
  }
  std::vector<CalibrationTerm> kept_terms;
  double current = before.rmse_m;
  res.train_after = res.train_before;
  for (std::size_t k = 0; k < loop.accepted.size(); ++k) {
    auto trial = kept_terms;
    trial.push_back(loop.accepted[k]);
    const auto fit = fit_calibration_model(data, res.train_rows, p.declared, trial);
    const double after =
        fit.status.ok() ? evaluate_model(fit.model, data, res.holdout_rows, p.declared.selection).rmse_m : kNaN;
    if (!confirmed(current, after, p)) {
      res.rejected_on_holdout.push_back(loop.accepted[k]);
      res.notes.push_back(
          fmt::format("{} of {} passed cross-validation but did not lower the held-out error "
                      "enough ({:.5f} -> {:.5f} m): dropped",
                      to_string(loop.accepted[k].form), loop.accepted[k].covariate, current, after));
      continue;
    }
    DiscoveredEffect e = loop.effects[k];
    e.rmse_before_m = current;
    e.rmse_after_m = after;
    res.effects.push_back(e);
    kept_terms = trial;
    kept_terms.back().rmse_before_m = current;
    kept_terms.back().rmse_after_m = after;
    current = after;
    res.train_after = fit.model;
  }
  res.rmse_after_m = current;
  return kept_terms;
}

// The low-pass filtered temperatures, when the temperature moves and the
// session lasts long enough to tell them from the reading itself.
CalibrationDataset with_time_covariates(const CalibrationDataset& data, const DiscoveryParams& p,
                                        std::vector<std::string>& notes) {
  if (p.temperature_lags_s.empty() || data.empty()) return data;
  double tmin = 1e300, tmax = -1e300, smin = 1e300, smax = -1e300;
  for (const auto& r : data.readouts) {
    tmin = std::min(tmin, r.temperature_c);
    tmax = std::max(tmax, r.temperature_c);
    smin = std::min(smin, r.t_s);
    smax = std::max(smax, r.t_s);
  }
  std::vector<double> taus;
  for (double tau : p.temperature_lags_s) {
    if (tau > 0.0 && 2.0 * tau <= smax - smin) taus.push_back(tau);
  }
  if (tmax - tmin < p.declared.min_temperature_span_c || taus.empty()) return data;
  notes.push_back(fmt::format("lagged temperatures tried: {} time constants from {:.0f} s", taus.size(), taus.front()));
  return with_lagged_temperature(data, taus);
}

std::vector<double> session_values(const CalibrationDataset& data, const std::vector<std::size_t>& rows) {
  const int col = data.extra_index("session");
  std::vector<double> v;
  if (col < 0) return v;
  for (std::size_t i : rows) v.push_back(data.readouts[i].extra[static_cast<std::size_t>(col)]);
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

// Whether term k of `terms` holds on another session: fitted on the first
// session's rows with and without it, judged on the other sessions' rows.
bool holds_on_other_session(const CalibrationDataset& data, const DiscoveryParams& p,
                            const std::vector<CalibrationTerm>& terms, std::size_t k,
                            const std::vector<std::size_t>& rows, std::string& why) {
  const auto sessions = session_values(data, rows);
  if (sessions.size() < 2) {
    why = "one session only: record another warm-up (a `session` column) to confirm it";
    return false;
  }
  const int col = data.extra_index("session");
  std::vector<std::size_t> first, others;
  for (std::size_t i : rows)
    (data.readouts[i].extra[static_cast<std::size_t>(col)] == sessions.front() ? first : others).push_back(i);
  std::vector<CalibrationTerm> without = terms;
  without.erase(without.begin() + static_cast<std::ptrdiff_t>(k));
  const auto a = fit_calibration_model(data, first, p.declared, without);
  const auto b = fit_calibration_model(data, first, p.declared, terms);
  const double before = a.status.ok() ? evaluate_model(a.model, data, others, p.declared.selection).rmse_m : kNaN;
  const double after = b.status.ok() ? evaluate_model(b.model, data, others, p.declared.selection).rmse_m : kNaN;
  why = fmt::format("fitted on session {}, the other sessions read {:.3f} -> {:.3f} cm", sessions.front(),
                    100.0 * before, 100.0 * after);
  return std::isfinite(before) && confirmed(before, after, p);
}

// A term on time since power-on is written only when it holds on another session.
void gate_on_sessions(DiscoveryResult& res, const CalibrationDataset& data, const DiscoveryParams& p,
                      std::vector<CalibrationTerm>& kept) {
  std::vector<std::size_t> rows = res.train_rows;
  rows.insert(rows.end(), res.holdout_rows.begin(), res.holdout_rows.end());
  for (std::size_t k = kept.size(); k-- > 0;) {
    if (covariate_from_name(kept[k].covariate) != Covariate::kTime) continue;
    std::string why;
    if (holds_on_other_session(data, p, kept, k, rows, why)) {
      res.notes.push_back(fmt::format("{} of t_s holds on another session ({})", to_string(kept[k].form), why));
      continue;
    }
    res.notes.push_back(
        fmt::format("{} of t_s (time since power-on) is reported, not written: {}", to_string(kept[k].form), why));
    res.unconfirmed_session.push_back(kept[k]);
    for (auto& e : res.effects) {
      if (e.covariate == kept[k].covariate && e.form == kept[k].form) e.written = false;
    }
    kept.erase(kept.begin() + static_cast<std::ptrdiff_t>(k));
  }
}

// Each effect's fitted term in physical units (from the model written, or for
// one not written, the training fit that holds it).
void read_effects(DiscoveryResult& res) {
  for (auto& e : res.effects) {
    for (const auto* m : {&res.model, &res.train_after}) {
      const auto& terms = m->impl().terms;
      const auto it = std::find_if(terms.begin(), terms.end(),
                                   [&](const auto& t) { return t.covariate == e.covariate && t.form == e.form; });
      if (it != terms.end()) {
        e.reading = term_reading(*it);
        break;
      }
    }
  }
}

void record_loop(DiscoveryResult& res, LoopOutcome& loop) {
  res.rounds = std::move(loop.rounds);
  res.candidates = loop.candidates;
  res.z_threshold = loop.z_threshold;
}

}  // namespace

// ------------------------------------------------------------------ discover_effects

DiscoveryResult discover_effects(const CalibrationDataset& input, const DiscoveryParams& given) {
  DiscoveryResult res;
  DiscoveryParams p = given;
  const CalibrationDataset data = with_time_covariates(input, p, res.notes);
  if (data.empty()) {
    res.status = common::Status::invalid(fmt::format("{}: no rows", data.source));
    return res;
  }
  if (p.folds < 2) {
    res.status = common::Status::invalid(fmt::format("{} folds: cross-validation needs at least 2", p.folds));
    return res;
  }
  if (p.declared.ceiling_from_data) {
    double plateau = kNaN;
    p.declared.validity = validity_from_data(data, p.declared.validity, &plateau);
    if (std::isfinite(plateau))
      res.notes.push_back(fmt::format("the read-outs saturate at {:.1f} charge_unit: validity ceiling {:.1f}", plateau,
                                      p.declared.validity.high));
  }
  std::size_t n_valid = 0;
  const std::vector<bool> valid = valid_rows(data, p.declared.validity, n_valid);
  if (n_valid == 0) {
    // Let the declared fit word the reason (counts by verdict).
    res.status = fit_declared_model(data, p.declared).status;
    return res;
  }
  Split split;
  if (!split_into(res, data, p, valid, split)) return res;
  if (p.declared.per_pulse_charge_levels && !surfaces_share_distances(data, valid)) {
    p.declared.per_pulse_charge_levels = false;
    res.notes.push_back(
        "one surface per target distance: charge terms per pulse are fitted without a level (their "
        "mean held at 0); a level would act as a distance cue");
  }

  // Each round: the declared model plus the accepted terms fitted on the training
  // groups fixes Rsen, leakage, X and the weights; the loop varies only linear terms.
  std::unique_ptr<detail::FitEngine> engine;
  std::string engine_problem;
  const Prepare prepare = [&](const std::vector<CalibrationTerm>& accepted) {
    engine = std::make_unique<detail::FitEngine>(data, res.train_rows, p.declared, accepted);
    RoundInput in;
    if (!engine->problem().empty()) {
      engine_problem = engine->problem();
      in.d.reference = &engine->amplitude_reference();
      return in;
    }
    engine->fit();
    if (accepted.empty()) res.train_before = engine->model();
    in.d = cv_data_from_engine(data, *engine, split, p.folds);
    in.d.rsen_per_pixel = p.declared.sensitivity_ratio_mode == SensitivityRatioMode::kPerPixel;
    in.d.rsen_min_rows = p.declared.min_rows_per_pixel;
    in.d.per_pulse_charge_levels = p.declared.per_pulse_charge_levels;
    for (const auto& t : accepted) in.accepted.push_back(evaluate_term(data, in.d, t));
    return in;
  };
  LoopOutcome loop = run_loop(data, prepare, p, res.notes);
  if (!engine_problem.empty()) {
    res.status = common::Status::invalid("fit on the training groups: " + engine_problem);
    return res;
  }
  record_loop(res, loop);
  std::vector<CalibrationTerm> kept_terms = confirm_on_holdout(res, data, p, loop);
  gate_on_sessions(res, data, p, kept_terms);
  res.heldout_eval_rows = select_readouts(data, res.holdout_rows, p.declared.validity, p.declared.selection);
  res.heldout_residual_before_m = model_residuals(res.train_before, data, res.heldout_eval_rows);
  res.heldout_residual_after_m = model_residuals(res.train_after, data, res.heldout_eval_rows);

  const auto final_fit = fit_calibration_model(data, {}, p.declared, kept_terms);
  if (!final_fit.status.ok()) {
    res.status = final_fit.status.within("final fit on all rows");
    return res;
  }
  res.model = final_fit.model;
  auto& info = res.model.impl().info;
  info.heldout_rmse_before_m = res.rmse_before_m;
  info.heldout_rmse_after_m = res.rmse_after_m;
  for (const auto& n : final_fit.notes) res.notes.push_back(n);
  read_effects(res);
  return res;
}

// ------------------------------------------------------------------ diagnose_model

namespace {

// Read-outs the given model gives a distance for and the driver would pick;
// `status` says why there are none (InvalidArgument).
std::vector<bool> diagnosable_rows(const CalibrationModel& model, const CalibrationDataset& data,
                                   const DiscoveryParams& p, std::vector<CalibrationEvaluation>& ev,
                                   common::Status& status) {
  const auto readouts = readouts_for_model(data, model);
  std::vector<bool> selected(data.size(), false);
  for (std::size_t i : select_readouts(data, {}, model.validity(), p.declared.selection)) selected[i] = true;
  std::vector<bool> valid(data.size());
  ev.assign(data.size(), {});
  std::size_t n_valid = 0, counts[5] = {0, 0, 0, 0, 0};
  for (std::size_t i = 0; i < data.size(); ++i) {
    ev[i] = model.evaluate(readouts[i]);
    if (!selected[i] && ev[i].status == CalibrationEvaluation::Status::kValid) {
      valid[i] = false;  // a valid read-out the driver would not pick
      continue;
    }
    ++counts[static_cast<int>(ev[i].status)];
    valid[i] = ev[i].status == CalibrationEvaluation::Status::kValid;
    n_valid += valid[i] ? 1 : 0;
  }
  if (n_valid == 0) {
    status = common::Status::invalid(
        fmt::format("the model gives no distance for any of the {} rows of {}: {} saturated, {} too dark, "
                    "{} outside its ratio range, {} missing a covariate",
                    data.size(), data.source, counts[1], counts[2], counts[3], counts[4]));
  }
  return valid;
}

// Residual mode: a constant plus the terms, fitted to truth - model.
CvData residual_cv_data(const CalibrationModel& model, const CalibrationDataset& data, const DiscoveryParams& p,
                        const std::vector<bool>& valid, const std::vector<CalibrationEvaluation>& ev,
                        const Split& split) {
  CvData d;
  d.folds = p.folds;
  d.base_cols = 1;
  d.reference = &model.impl().amplitude_reference;
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (!valid[i] || split.group[i] < 0) continue;
    const auto g = static_cast<std::size_t>(split.group[i]);
    d.row.push_back(i);
    d.base.push_back(Entries{{0, 1.0}});
    d.y.push_back(data.distance_m[i] - ev[i].distance_m);
    d.w.push_back(1.0);
    d.x.push_back(ev[i].ratio);
    d.declared.push_back(ev[i].declared_distance_m);
    d.amplitude.push_back(data.readouts[i].a + data.readouts[i].b);
    d.fold.push_back(split.holdout[g] ? -2 : split.fold[g]);
  }
  dense_cv_groups(d, split);
  return d;
}

double residual_heldout_rmse(const CvData& d, const std::vector<double>* pred) {
  double sse = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    if (d.fold[i] != -2) continue;
    const double r = d.y[i] - (pred ? (*pred)[i] : 0.0);
    sse += r * r;
    ++n;
  }
  return n ? std::sqrt(sse / static_cast<double>(n)) : kNaN;
}

// The diagnosis's counterpart of confirm_on_holdout: terms fitted to the residuals.
void confirm_residual_terms(DiscoveryResult& res, const CalibrationDataset& data, const DiscoveryParams& p,
                            const CvData& d, const LoopOutcome& loop) {
  res.rmse_before_m = residual_heldout_rmse(d, nullptr);
  double current = res.rmse_before_m;
  std::vector<CvTerm> evaluated;
  for (const auto& t : loop.accepted) evaluated.push_back(evaluate_term(data, d, t));
  std::vector<const CvTerm*> kept;
  for (std::size_t k = 0; k < evaluated.size(); ++k) {
    auto trial = kept;
    trial.push_back(&evaluated[k]);
    const auto pred = fit_and_predict(d, trial, p.declared.term_ridge);
    const double after = residual_heldout_rmse(d, &pred);
    if (!confirmed(current, after, p)) {
      res.rejected_on_holdout.push_back(loop.accepted[k]);
      continue;
    }
    DiscoveredEffect e = loop.effects[k];
    e.rmse_before_m = current;
    e.rmse_after_m = after;
    res.effects.push_back(e);
    kept = trial;
    current = after;
  }
  res.rmse_after_m = current;
  const auto pred = fit_and_predict(d, kept, p.declared.term_ridge);
  for (std::size_t i = 0; i < d.y.size(); ++i) {
    if (d.fold[i] != -2) continue;
    res.heldout_eval_rows.push_back(d.row[i]);
    res.heldout_residual_before_m.push_back(-d.y[i]);  // y = truth - model
    res.heldout_residual_after_m.push_back(kept.empty() ? -d.y[i] : pred[i] - d.y[i]);
  }
}

}  // namespace

DiscoveryResult diagnose_model(const CalibrationModel& model, const CalibrationDataset& data,
                               const DiscoveryParams& p) {
  DiscoveryResult res;
  res.model = model;
  if (data.empty()) {
    res.status = common::Status::invalid(fmt::format("{}: no rows", data.source));
    return res;
  }
  std::vector<CalibrationEvaluation> ev;
  const std::vector<bool> valid = diagnosable_rows(model, data, p, ev, res.status);
  if (!res.status.ok()) return res;
  Split split;
  if (!split_into(res, data, p, valid, split)) return res;
  const CvData d = residual_cv_data(model, data, p, valid, ev, split);
  const Prepare prepare = [&](const std::vector<CalibrationTerm>& accepted) {
    RoundInput in;
    in.d = d;  // residual mode: the model stays as given
    for (const auto& t : accepted) in.accepted.push_back(evaluate_term(data, d, t));
    return in;
  };
  LoopOutcome loop = run_loop(data, prepare, p, res.notes);
  record_loop(res, loop);
  confirm_residual_terms(res, data, p, d, loop);
  return res;
}

}  // namespace tinyline::tiny_laser_calibration
