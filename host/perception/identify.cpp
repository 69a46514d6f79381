// identify.cpp - rotation-, flip- and mirror-aware comparison of identity profiles.
#include "identify.hpp"

#include <algorithm>
#include <cmath>

namespace rbx1::vision {

std::vector<double> identity_profile(const Geometry& g, const Pose& p, const RayHits& hits, int lines) {
  const int rays = 2 * lines;
  const double step = M_PI / lines;
  const double scale = 1.0 / std::sqrt(std::max(g.area_px, 1.0));
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

}  // namespace

Match identify(const Library& lib, const std::vector<double>& profile, double area_px, std::optional<double> area_cm2,
               double elongation, const MatchOptions& opt) {
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
    double best_rms = 1e300;
    for (int mirror = 0; mirror <= (ref.mirror_ok ? 1 : 0); ++mirror) {
      const std::vector<double>& p = seen[mirror];
      for (int s : shifts) {
        // Each side's value against the other's range nearby, both ways: symmetric, 0 for identical profiles.
        double acc = 0;
        for (int k = 0; k < n; ++k) {
          size_t q = size_t(((k + s) % n + n) % n), j = size_t(k);
          double a = outside(p[j], ref_lo[q], ref_hi[q]), b = outside(ref.profile[q], seen_lo[mirror][j], seen_hi[mirror][j]);
          acc += 0.5 * (a * a + b * b);
          if (acc >= best_rms * best_rms * n) break;  // cannot beat the best any more
        }
        best_rms = std::min(best_rms, std::sqrt(acc / n));
      }
    }
    double size_dev = 0;
    if (opt.size_sigma > 0) {
      size_dev = (area_cm2 && ref.area_cm2) ? 0.5 * std::log(*area_cm2 / *ref.area_cm2) : 0.5 * std::log(area_px / ref.area_px);
      if (size_dev > 0) size_dev = std::max(0.0, size_dev - std::log1p(std::max(0.0, opt.size_grow)));
      size_dev /= opt.size_sigma;
    }
    double z = best_rms / opt.shape_sigma;
    double score = std::exp(-0.5 * (z * z + size_dev * size_dev));
    if (best.entry < 0 || score > best.score) best.entry = int(e), best.score = score;
  }
  return best;
}

}  // namespace rbx1::vision
