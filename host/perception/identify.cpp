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

Match identify(const Library& lib, const std::vector<double>& profile, double area_px, std::optional<double> area_cm2,
               double elongation, const MatchOptions& opt) {
  Match best;
  const int n = kProfileBins;
  // A clear axis fixes the rotation up to the 180-degree flip (plus a little slack); otherwise try all.
  std::vector<int> shifts;
  if (elongation >= 1.3) {
    for (int s = -3; s <= 3; ++s) shifts.push_back(s), shifts.push_back(n / 2 + s);
  } else {
    for (int s = 0; s < n; ++s) shifts.push_back(s);
  }
  for (size_t e = 0; e < lib.entries.size(); ++e) {
    const LibraryEntry& ref = lib.entries[e];
    double best_rms = 1e300;
    for (int mirror = 0; mirror <= (ref.mirror_ok ? 1 : 0); ++mirror) {
      for (int s : shifts) {
        double acc = 0;
        for (int j = 0; j < n; ++j) {
          int k = mirror ? (n - j) % n : j;  // mirror about the axis: angle -> -angle
          int q = ((k + s) % n + n) % n;
          double dv = profile[size_t(j)] - ref.profile[size_t(q)];
          acc += dv * dv;
          if (acc >= best_rms * best_rms * n) break;  // cannot beat the best any more
        }
        best_rms = std::min(best_rms, std::sqrt(acc / n));
      }
    }
    double size_dev = 0;
    if (opt.size_sigma > 0) {
      size_dev = (area_cm2 && ref.area_cm2) ? 0.5 * std::log(*area_cm2 / *ref.area_cm2) : 0.5 * std::log(area_px / ref.area_px);
      size_dev /= opt.size_sigma;
    }
    double z = best_rms / opt.shape_sigma;
    double score = std::exp(-0.5 * (z * z + size_dev * size_dev));
    if (best.entry < 0 || score > best.score) best.entry = int(e), best.score = score;
  }
  return best;
}

}  // namespace rbx1::vision
