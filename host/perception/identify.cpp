// identify.cpp - rotation-, flip- and mirror-aware comparison of identity profiles.
#include "identify.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

namespace rbx1::vision {

std::vector<double> identity_profile(const Geometry& g, const Pose& p, const RayHits& hits, int lines) {
  const int rays = 2 * lines;
  const double step = M_PI / lines;
  const double scale = 1.0 / std::sqrt(std::max(g.half_area_px, 1.0));
  std::vector<double> out(static_cast<size_t>(kProfileBins));
  for (int j = 0; j < kProfileBins; ++j) {
    double psi = p.orientation_deg * M_PI / 180 + j * 2 * M_PI / kProfileBins;
    double f = psi / step;
    int i0 = int(std::floor(f));
    double a = f - i0;
    auto r = [&](int i) { return std::max(0.0, hits.rmax[size_t(((i % rays) + rays) % rays)]); };
    out[size_t(j)] = ((1 - a) * r(i0) + a * r(i0 + 1)) * scale;
  }
  return out;
}

namespace {

// The lowest and highest value of a circular profile over +-k bins around each bin.
void envelope(const std::vector<double>& v, int k, std::vector<double>& lo, std::vector<double>& hi) {
  const int n = int(v.size());
  lo.assign(v.begin(), v.end());
  hi.assign(v.begin(), v.end());
  for (int j = 0; j < n; ++j) {
    for (int d = 1; d <= k; ++d) {
      for (int q : {(j + d) % n, (j - d + n) % n}) {
        lo[size_t(j)] = std::min(lo[size_t(j)], v[size_t(q)]);
        hi[size_t(j)] = std::max(hi[size_t(j)], v[size_t(q)]);
      }
    }
  }
}

// How far x lies outside [lo, hi].
double outside(double x, double lo, double hi) { return x > hi ? x - hi : (x < lo ? lo - x : 0.0); }

// The seen object's area and the profile's scale factor as `ref` measures them.
double size_deviation(const LibraryEntry& ref, const SeenArea& seen, double& profile_scale) {
  const bool layer = ref.area_kind == AreaKind::Layer;
  const double px = layer ? seen.layer_px : seen.half_px;
  profile_scale = layer ? std::sqrt(seen.half_px / std::max(seen.layer_px, 1.0)) : 1.0;
  if (seen.px_per_cm > 0 && ref.area_cm2) return 0.5 * std::log(px / (seen.px_per_cm * seen.px_per_cm) / *ref.area_cm2);
  return 0.5 * std::log(px / ref.area_px);
}

}  // namespace

Match identify(const Library& lib, const std::vector<double>& profile, const SeenArea& area, double elongation,
               const MatchOptions& opt) {
  Match best;
  const int n = kProfileBins;
  const int slack = std::max(0, opt.angle_slack_bins);
  // A clear axis fixes the rotation up to the 180-degree flip (plus a little slack); otherwise try all.
  std::vector<int> shifts;
  if (elongation >= 1.3) {
    for (int s = -3; s <= 3; ++s) shifts.push_back(s), shifts.push_back(n / 2 + s);
  } else {
    for (int s = 0; s < n; ++s) shifts.push_back(s);
  }
  // The profile as seen (and mirrored about the axis: angle -> -angle) with its envelopes.
  std::vector<double> seen[2], seen_lo[2], seen_hi[2];
  for (int mirror = 0; mirror <= 1; ++mirror) {
    seen[mirror].resize(size_t(n));
    for (int k = 0; k < n; ++k) seen[mirror][size_t(k)] = profile[size_t(mirror ? (n - k) % n : k)];
    envelope(seen[mirror], slack, seen_lo[mirror], seen_hi[mirror]);
  }
  std::vector<double> ref_lo, ref_hi;
  for (size_t e = 0; e < lib.entries.size(); ++e) {
    const LibraryEntry& ref = lib.entries[e];
    envelope(ref.profile, slack, ref_lo, ref_hi);
    double f = 1;  // the seen profile's scale as this entry measures area
    double size_dev = size_deviation(ref, area, f);
    double best_rms = 1e300;
    for (int mirror = 0; mirror <= (ref.mirror_ok ? 1 : 0); ++mirror) {
      const std::vector<double>& p = seen[mirror];
      for (int s : shifts) {
        // Each side's value against the other's range nearby, both ways: symmetric, 0 for identical profiles.
        double acc = 0;
        for (int k = 0; k < n; ++k) {
          size_t q = size_t(((k + s) % n + n) % n), j = size_t(k);
          double a = outside(f * p[j], ref_lo[q], ref_hi[q]),
                 b = outside(ref.profile[q], f * seen_lo[mirror][j], f * seen_hi[mirror][j]);
          acc += 0.5 * (a * a + b * b);
          if (acc >= best_rms * best_rms * n) break;  // cannot beat the best any more
        }
        best_rms = std::min(best_rms, std::sqrt(acc / n));
      }
    }
    if (opt.size_sigma > 0) {
      if (size_dev > 0) size_dev = std::max(0.0, size_dev - std::log1p(std::max(0.0, opt.size_grow)));
      size_dev /= opt.size_sigma;
    } else {
      size_dev = 0;
    }
    double z = best_rms / opt.shape_sigma;
    double score = std::exp(-0.5 * (z * z + size_dev * size_dev));
    if (best.entry < 0 || score > best.score) {
      best.runner_up = best.entry, best.runner_up_score = best.score;
      best.entry = int(e), best.score = score;
    } else if (best.runner_up < 0 || score > best.runner_up_score) {
      best.runner_up = int(e), best.runner_up_score = score;
    }
  }
  return best;
}

const char* verdict_name(Verdict v) {
  switch (v) {
    case Verdict::Known: return "known";
    case Verdict::NoLibrary: return "no_library";
    case Verdict::BelowThreshold: return "below_threshold";
    case Verdict::Ambiguous: return "ambiguous";
  }
  return "?";
}

double entry_threshold(const LibraryEntry& e, const MatchOptions& opt) {
  return std::max(opt.threshold, e.threshold.value_or(0.0));
}

Verdict judge(const Library& lib, const Match& m, const MatchOptions& opt) {
  if (m.entry < 0) return Verdict::NoLibrary;
  if (m.score < entry_threshold(lib.entries[size_t(m.entry)], opt)) return Verdict::BelowThreshold;
  if (m.runner_up >= 0 && m.runner_up_score >= entry_threshold(lib.entries[size_t(m.runner_up)], opt) &&
      m.score - m.runner_up_score < opt.min_margin)
    return Verdict::Ambiguous;
  return Verdict::Known;
}

Identity identity_of(const Library& lib, const Match& m, const MatchOptions& opt) {
  Identity id;
  id.verdict = judge(lib, m, opt);
  if (m.entry < 0) return id;
  const LibraryEntry& best = lib.entries[size_t(m.entry)];
  id.best = best.name;
  id.best_score = m.score;
  id.threshold = entry_threshold(best, opt);
  if (m.runner_up >= 0) id.runner_up = lib.entries[size_t(m.runner_up)].name, id.runner_up_score = m.runner_up_score;
  if (id.verdict == Verdict::Known) id.label = best.name, id.score = m.score;
  return id;
}

namespace {

// Area centroid and central second moments (per unit area) of a closed polygon (Green's theorem); false when
// it encloses no area.
bool polygon_moments(const std::vector<EdgePoint>& c, Geometry& g) {
  const size_t n = c.size();
  const double x0 = c[0].x, y0 = c[0].y;  // moments about a point on the polygon, for precision
  double a2 = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  for (size_t i = 0; i < n; ++i) {
    double ax = c[i].x - x0, ay = c[i].y - y0, bx = c[(i + 1) % n].x - x0, by = c[(i + 1) % n].y - y0;
    double cr = ax * by - bx * ay;
    a2 += cr, sx += (ax + bx) * cr, sy += (ay + by) * cr;
    sxx += (ax * ax + ax * bx + bx * bx) * cr, syy += (ay * ay + ay * by + by * by) * cr;
    sxy += (ax * by + 2 * ax * ay + 2 * bx * by + bx * ay) * cr;
  }
  if (std::abs(a2) < 1e-9) return false;
  double cx = sx / (3 * a2), cy = sy / (3 * a2);
  g.centroid = {cx + x0, cy + y0};
  g.mu20 = sxx / (6 * a2) - cx * cx;
  g.mu02 = syy / (6 * a2) - cy * cy;
  g.mu11 = sxy / (12 * a2) - cx * cy;
  return true;
}

double signed_area(const std::vector<EdgePoint>& c) {
  double a2 = 0;
  for (size_t i = 0; i < c.size(); ++i) a2 += c[i].x * c[(i + 1) % c.size()].y - c[(i + 1) % c.size()].x * c[i].y;
  return a2 / 2;
}

// The px per cm an entry was taught at (0 when uncalibrated).
double entry_scale(const LibraryEntry& e) { return e.area_cm2 ? std::sqrt(e.area_px / *e.area_cm2) : 0.0; }

// One view of the taught contour: each point moved along its outward normal by offset + noise, then scaled and
// turned about the centroid; weights, centroid, moments and area measured again (psi/rho left to cast_rays).
Geometry view_of(const Geometry& g, double turn, double scale, double offset, double noise, std::mt19937& rng) {
  const auto& c = g.contour;
  const size_t n = c.size();
  const double orient = signed_area(c) >= 0 ? 1 : -1;
  std::normal_distribution<double> jitter(0, noise);
  const double cs = std::cos(turn), sn = std::sin(turn);
  Geometry v;
  v.contour.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const EdgePoint& a = c[(i + n - 1) % n];
    const EdgePoint& b = c[(i + 1) % n];
    double tx = b.x - a.x, ty = b.y - a.y, len = std::max(std::hypot(tx, ty), 1e-9);
    double d = offset + jitter(rng);
    double x = c[i].x + d * orient * ty / len - g.centroid.x, y = c[i].y - d * orient * tx / len - g.centroid.y;
    v.contour[i] = {g.centroid.x + scale * (cs * x - sn * y), g.centroid.y + scale * (sn * x + cs * y), 1};
  }
  for (size_t i = 0; i < n; ++i) {
    const EdgePoint &p = v.contour[(i + n - 1) % n], &q = v.contour[i], &r = v.contour[(i + 1) % n];
    v.contour[i].w = 0.5 * (std::hypot(q.x - p.x, q.y - p.y) + std::hypot(r.x - q.x, r.y - q.y));
  }
  const double grown = std::abs(signed_area(v.contour) / signed_area(c));
  v.area_px = g.area_px * grown;
  v.half_area_px = g.half_area_px * grown;
  if (!polygon_moments(v.contour, v)) v.centroid = g.centroid;
  return v;
}

}  // namespace

SelfViews learn_threshold(const Geometry& g, const LibraryEntry& entry, const MatchOptions& opt,
                          const PoseOptions& pose, int lines) {
  SelfViews out;
  out.threshold = opt.threshold;
  if (g.contour.size() < 3 || std::abs(signed_area(g.contour)) < 1) return out;
  Library self;
  self.entries.push_back(entry);
  self.entries.back().threshold.reset();
  std::mt19937 rng(27);  // the same views every time: teaching the same frame gives the same threshold
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> scores;
  for (int k = 0; k < kSelfViews; ++k) {
    double turn = 2 * M_PI * (k + 0.5 * (U(rng) + 1)) / kSelfViews;
    Geometry v = view_of(g, turn, 1 + kViewScale * U(rng), kViewOffsetPx * U(rng), kViewNoisePx, rng);
    Pose p = estimate_pose(v, pose);
    std::vector<double> prof = identity_profile(v, p, cast_rays(v, lines), lines);
    scores.push_back(identify(self, prof, SeenArea::of(v, entry_scale(entry)), p.elongation, opt).score);
  }
  std::sort(scores.begin(), scores.end());
  out.worst = scores.front();
  out.median = scores[scores.size() / 2];
  // In the score's exponent: z = sqrt(-2 ln score) of the worst view, widened, at least kThresholdMinZ.
  double z = std::max(kThresholdMinZ, kThresholdSpread * std::sqrt(-2 * std::log(std::max(out.worst, 1e-12))));
  out.threshold = std::max(opt.threshold, std::exp(-0.5 * z * z));
  return out;
}

std::vector<Lookalike> lookalikes(const Library& lib, const LibraryEntry& entry, const MatchOptions& opt) {
  std::vector<Lookalike> out;
  const double own = entry_threshold(entry, opt);
  for (const LibraryEntry& other : lib.entries) {
    if (other.name == entry.name) continue;  // the same name is replaced, not doubled
    Library one;
    one.entries.push_back(other);
    // The new entry's layer area is not kept: against an entry of that kind its profile is compared unscaled.
    const SeenArea area{entry.area_px, entry.area_px, entry_scale(entry)};
    const double score = identify(one, entry.profile, area, entry.elongation, opt).score;
    const double theirs = entry_threshold(other, opt);
    if (score < std::min(own, theirs)) continue;
    out.push_back({other.name, score, score >= theirs ? theirs : own, 1 - score < opt.min_margin});
  }
  return out;
}

std::string lookalike_warning(const std::string& taught, const Lookalike& l) {
  char figures[96];
  std::snprintf(figures, sizeof figures, "match %.3f, threshold %.3f", l.score, l.threshold);
  const std::string both = "\"" + taught + "\" and \"" + l.name + "\"";
  return "\"" + taught + "\" looks like \"" + l.name + "\" already in the library (" + figures + "): " +
         (l.ambiguous ? "an object of either shape will be ambiguous, so picks by " + both +
                            " will answer unknown (ambiguous) for both"
                      : "close look-alikes; a view a little off may be unknown (ambiguous) for " + both) +
         "; teach one name per object (teaching the same name again replaces it)";
}

}  // namespace rbx1::vision
