// split.cpp - touching objects cut at their necks (distance-transform maxima ranked by persistence, watershed), and
// bodies of clearly different contrast re-cut where their contrast changes.
#include "split.hpp"

#include <algorithm>
#include <numeric>
#include <queue>

#include <opencv2/imgproc.hpp>

#include "pixels.hpp"

namespace rbx1::vision {
namespace {

int find(std::vector<int>& parent, int i) {
  while (parent[size_t(i)] != i) i = parent[size_t(i)] = parent[size_t(parent[size_t(i)])];
  return i;
}

// The two ends of the cut between bodies a and b: of the pixels on either side of the cut that touch the
// outside (4-neighbours), the two farthest apart.
struct CutEnds { bool found = false; cv::Point e1, e2; };

CutEnds cut_ends(const cv::Mat& parts, const cv::Mat& mask, int a, int b) {
  std::vector<cv::Point> ends;
  const int w = parts.cols, h = parts.rows;
  auto label = [&](int x, int y) { return x < 0 || y < 0 || x >= w || y >= h ? 0 : parts.at<int>(y, x); };
  auto outside = [&](int x, int y) { return x < 0 || y < 0 || x >= w || y >= h || !mask.at<uchar>(y, x); };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int l = parts.at<int>(y, x);
      if (l != a && l != b) continue;
      const int other = l == a ? b : a;
      bool on_cut = false;
      for (int dy = -1; dy <= 1 && !on_cut; ++dy)
        for (int dx = -1; dx <= 1 && !on_cut; ++dx) on_cut = label(x + dx, y + dy) == other;
      if (on_cut && (outside(x - 1, y) || outside(x + 1, y) || outside(x, y - 1) || outside(x, y + 1)))
        ends.push_back({x, y});
    }
  CutEnds c;
  double best = -1;
  for (size_t i = 0; i < ends.size(); ++i)
    for (size_t j = i + 1; j < ends.size(); ++j) {
      const double d = cv::norm(ends[i] - ends[j]);
      if (d > best) best = d, c.e1 = ends[i], c.e2 = ends[j], c.found = true;
    }
  return c;
}

// Whether two bodies meet at a pinch: the neck's half width h (the distance transform's maximum along the cut
// between a and b), then on each side the distance from the cut to the nearest pixel where the region is
// (1 + opening) times as wide (h + max(2, opening h) from the outline). Two objects touching widen at once on
// either side of the contact: both distances come to about 1.5 h (a star's tip, a wedge, 5 h on its side);
// a stem, a handle's shaft or a dumbbell's bar stays h wide for its length, on one side of the cut or split
// between both, so the two distances add up to more than 4 h + 8 px (a 1 px contact beside a wedge: 10.3).
bool widens_from_neck(const cv::Mat& parts, const cv::Mat& dist, int a, int b, double opening) {
  const int w = parts.cols, h = parts.rows;
  cv::Mat not_cut(parts.size(), CV_8U, cv::Scalar(255));
  double neck = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int l = parts.at<int>(y, x);
      if (l != a && l != b) continue;
      const int other = l == a ? b : a;
      bool on_cut = false;
      for (int dy = -1; dy <= 1 && !on_cut; ++dy)
        for (int dx = -1; dx <= 1 && !on_cut; ++dx) {
          const int qx = x + dx, qy = y + dy;
          on_cut = qx >= 0 && qy >= 0 && qx < w && qy < h && parts.at<int>(qy, qx) == other;
        }
      if (on_cut) not_cut.at<uchar>(y, x) = 0, neck = std::max(neck, double(dist.at<float>(y, x)));
    }
  cv::Mat from_cut;
  cv::distanceTransform(not_cut, from_cut, cv::DIST_L2, 3);
  const double wide = neck + std::max(2.0, opening * neck);
  double to_a = 1e9, to_b = 1e9;  // from the cut to the nearest wide pixel on each side
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int l = parts.at<int>(y, x);
      if ((l != a && l != b) || dist.at<float>(y, x) < wide) continue;
      double& m = l == a ? to_a : to_b;
      m = std::min(m, double(from_cut.at<float>(y, x)));
    }
  return to_a + to_b <= 4 * neck + 8;
}

}  // namespace

int split_touching(const cv::Mat& mask, const SplitOptions& opt, cv::Mat& parts) {
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  if (contours.size() != 1) return 1;
  std::vector<cv::Point> hull;
  cv::convexHull(contours[0], hull);
  double area = cv::contourArea(contours[0]), hull_area = cv::contourArea(hull);
  if (hull_area <= 0 || area / hull_area > opt.max_solidity || area < 2 * opt.min_area_px) return 1;

  // Distance to the background, on a 1-px padded copy so the ROI's edge counts as outside.
  cv::Mat padded, dist;
  cv::copyMakeBorder(mask, padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::distanceTransform(padded, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  dist = dist(cv::Rect(1, 1, mask.cols, mask.rows)).clone();

  // Flood from the top (0-dimensional persistence): pixels in decreasing distance join their neighbours'
  // sets; when two sets meet at level s, the one with the lower peak dies with persistence peak - s.
  const int w = mask.cols, h = mask.rows;
  std::vector<int> idx;
  idx.reserve(size_t(cv::countNonZero(mask)));
  for (int y = 0; y < h; ++y) {
    const uchar* m = mask.ptr<uchar>(y);
    for (int x = 0; x < w; ++x)
      if (m[x]) idx.push_back(y * w + x);
  }
  const float* dv = dist.ptr<float>();
  std::sort(idx.begin(), idx.end(), [&](int a, int b) { return dv[a] > dv[b]; });
  std::vector<int> parent(size_t(w * h), -1);
  std::vector<float> peak(size_t(w * h), 0);
  std::vector<cv::Point> peak_at(size_t(w * h));
  struct Body { cv::Point at; float peak; float persistence; };
  std::vector<Body> dead;
  for (int p : idx) {
    parent[size_t(p)] = p;
    peak[size_t(p)] = dv[p];
    peak_at[size_t(p)] = {p % w, p / w};
    const int px = p % w, py = p / w;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        int qx = px + dx, qy = py + dy;
        if ((dx == 0 && dy == 0) || qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
        int q = qy * w + qx;
        if (parent[size_t(q)] < 0) continue;
        int a = find(parent, p), b = find(parent, q);
        if (a == b) continue;
        if (peak[size_t(a)] < peak[size_t(b)]) std::swap(a, b);  // a keeps the higher peak
        dead.push_back({peak_at[size_t(b)], peak[size_t(b)], peak[size_t(b)] - dv[p]});
        parent[size_t(b)] = a;
      }
  }
  // The survivor (highest peak) plus every body that stood out enough.
  std::vector<cv::Point> seeds;
  if (idx.empty()) return 1;
  seeds.push_back(peak_at[size_t(find(parent, idx.front()))]);
  // A neck at least half as wide as the body is a waist of one object (a propeller's hub, a lighter under its
  // cap: 36 % and 35 % persistence on the corpus photos), not two objects touching (discs: ~80 %).
  const double rel = std::max(opt.min_persistence_rel, 0.5);
  for (const Body& b : dead)
    if (b.persistence >= opt.min_persistence_px && b.persistence >= rel * b.peak &&
        b.peak * b.peak * 3.0 >= opt.min_area_px)
      seeds.push_back(b.at);
  if (seeds.size() < 2) return 1;

  // Marker watershed on the distance (flooding from the bodies' peaks, highest pixels first): each pixel
  // joins the body that reaches it from above, so the cuts run along the necks. cv::watershed would rank
  // pixels by colour difference to their neighbours instead of by height, which does not follow a neck.
  parts = cv::Mat(mask.size(), CV_32S, cv::Scalar(0));
  using Item = std::pair<float, int>;
  std::priority_queue<Item> queue;
  for (size_t i = 0; i < seeds.size(); ++i) {
    int p = seeds[i].y * w + seeds[i].x;
    parts.at<int>(seeds[i]) = int(i) + 1;
    queue.push({dv[p], p});
  }
  int* pv = parts.ptr<int>();
  const uchar* mv = mask.ptr<uchar>();
  while (!queue.empty()) {
    const int p = queue.top().second;
    queue.pop();
    const int px = p % w, py = p / w, lab = pv[p];
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        int qx = px + dx, qy = py + dy;
        if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
        int q = qy * w + qx;
        if (!mv[q] || pv[q]) continue;
        pv[q] = lab;
        queue.push({dv[q], q});
      }
  }
  // Bodies too small after the cut are not objects: give up the split rather than leave a sliver.
  std::vector<int> count(seeds.size() + 1, 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) count[size_t(std::max(0, parts.at<int>(y, x)))]++;
  for (size_t i = 1; i < count.size(); ++i)
    if (count[i] < opt.min_area_px) return 1;

  // A cut between two objects that touch runs from a concavity of the outline to another: the table comes in
  // on both sides of the contact (on the scene generator's touching pairs both ends lie 3.75 px or more inside
  // the region's convex hull). A cut with an end on a straight side (stuff.jpg's lighter: its metal head joined
  // to its body along one side only, the light band under the head at the table's grey; that end 1.6 px deep)
  // is a waist of one object: its bodies are joined again.
  const int n = int(seeds.size());
  std::vector<int> merged(size_t(n + 1));
  std::iota(merged.begin(), merged.end(), 0);
  std::vector<std::vector<CutEnds>> cut(size_t(n + 1), std::vector<CutEnds>(size_t(n + 1)));
  std::vector<int> neighbours(size_t(n + 1), 0);
  for (int a = 1; a <= n; ++a)
    for (int b = a + 1; b <= n; ++b)
      if ((cut[size_t(a)][size_t(b)] = cut_ends(parts, mask, a, b)).found) ++neighbours[size_t(a)], ++neighbours[size_t(b)];
  for (int a = 1; a <= n; ++a)
    for (int b = a + 1; b <= n; ++b) {
      const CutEnds& c = cut[size_t(a)][size_t(b)];
      if (!c.found) continue;
      const double d1 = cv::pointPolygonTest(hull, cv::Point2f(c.e1), true);
      const double d2 = cv::pointPolygonTest(hull, cv::Point2f(c.e2), true);
      // Both bodies objects on their own: a body far smaller than the one it hangs from (a leaf on its stem, a
      // crown's ball on its prong, a jellyfish's bulb) or a neck that does not widen into both bodies (a stem,
      // a handle's shaft cut along its length) is a narrow part of one object (issue 27: 3 of 20 silhouettes).
      // A part hangs from one body: a small body between two or more (the shade joining two sweets,
      // smarties.png) is left to the shade and fringe tests, as before.
      const int smaller = count[size_t(a)] < count[size_t(b)] ? a : b;
      const bool hangs = neighbours[size_t(smaller)] == 1;
      const bool small = std::min(count[size_t(a)], count[size_t(b)]) <
                         opt.min_body_ratio * std::max(count[size_t(a)], count[size_t(b)]);
      if (std::min(d1, d2) < opt.min_cut_depth_px ||
          (hangs && (small || !widens_from_neck(parts, dist, a, b, opt.neck_opening)))) {
        int ra = find(merged, a), rb = find(merged, b);
        if (ra != rb) merged[size_t(std::max(ra, rb))] = std::min(ra, rb);
      }
    }
  std::vector<int> renumber(size_t(n + 1), 0);
  int bodies = 0;
  for (int i = 1; i <= n; ++i)
    if (find(merged, i) == i) renumber[size_t(i)] = ++bodies;
  if (bodies < 2) return 1;
  for (int i = 1; i <= n; ++i) renumber[size_t(i)] = renumber[size_t(find(merged, i))];
  for (int y = 0; y < h; ++y) {
    int* row = parts.ptr<int>(y);
    for (int x = 0; x < w; ++x) row[x] = renumber[size_t(std::max(0, row[x]))];
  }
  return bodies;
}

void cut_between_levels(const cv::Mat& contrast, double noise_sigma, int bodies, cv::Mat& parts) {
  const int w = parts.cols, h = parts.rows, n = bodies;
  // Each body's level: the median contrast over its pixels.
  std::vector<std::vector<int>> hist(size_t(n + 1), std::vector<int>(256, 0));
  std::vector<int> count(size_t(n + 1), 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int l = parts.at<int>(y, x);
      if (l > 0 && l <= n) hist[size_t(l)][contrast.at<uchar>(y, x)]++, count[size_t(l)]++;
    }
  std::vector<int> level(size_t(n + 1), 0);
  for (int l = 1; l <= n; ++l)
    for (int acc = 0; level[size_t(l)] < 255 && (acc += hist[size_t(l)][size_t(level[size_t(l)])]) * 2 < count[size_t(l)];)
      ++level[size_t(l)];
  // Neighbours (8-connected) of clearly different levels.
  std::vector<std::vector<char>> apart(size_t(n + 1), std::vector<char>(size_t(n + 1), 0));
  bool any = false;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int a = parts.at<int>(y, x);
      if (a <= 0) continue;
      for (int dy = 0; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int qx = x + dx, qy = y + dy;
          if ((dy == 0 && dx <= 0) || qx < 0 || qx >= w || qy >= h) continue;
          const int b = parts.at<int>(qy, qx);
          if (b <= 0 || b == a) continue;
          const int la = level[size_t(a)], lb = level[size_t(b)];
          if (std::abs(la - lb) >= std::max(4 * noise_sigma, 0.2 * std::max(la, lb)))
            apart[size_t(a)][size_t(b)] = apart[size_t(b)][size_t(a)] = any = true;
        }
    }
  if (!any) return;
  // The band within 2 px of the outline holds the bodies' edges over the table, at every level between the
  // table's and their own (a dark body's rim passes through a lighter neighbour's level): no evidence for one
  // body or the other. It takes no part in the seeds and joins the nearest body once the rest is cut.
  cv::Mat near_out;
  dilate_square(parts == 0, near_out, 2);
  // The seeds: per body, its pixels off the band on its own side of every half-way level, largest connected part.
  cv::Mat own(h, w, CV_8U, cv::Scalar(0)), seeds(h, w, CV_32S, cv::Scalar(0));
  for (int l = 1; l <= n; ++l) {
    own.setTo(0);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        if (parts.at<int>(y, x) != l) continue;
        const int c = contrast.at<uchar>(y, x);
        bool mine = true;
        for (int o = 1; o <= n && mine; ++o)
          mine = !apart[size_t(l)][size_t(o)] || std::abs(c - level[size_t(l)]) < std::abs(c - level[size_t(o)]);
        own.at<uchar>(y, x) = mine && !near_out.at<uchar>(y, x) ? 255 : 0;
      }
    cv::Mat comp, stats, centres;
    const int nc = cv::connectedComponentsWithStats(own, comp, stats, centres, 8, CV_32S);
    int best = 0;
    for (int i = 1; i < nc; ++i)
      if (!best || stats.at<int>(i, cv::CC_STAT_AREA) > stats.at<int>(best, cv::CC_STAT_AREA)) best = i;
    if (best) seeds.setTo(l, comp == best);
  }
  // Seeded region growing over the rest of the bodies' pixels: the pixel closest to the level of the body
  // beside it joins that body first; then the band, nearest first (its key: 1000 + steps from the rest).
  using Item = std::pair<int, int>;  // (-key, pixel * (n + 1) + label)
  std::priority_queue<Item> queue;
  int* sv = seeds.ptr<int>();
  const int* pv = parts.ptr<int>();
  const uchar* cv_ = contrast.ptr<uchar>();
  const uchar* bv = near_out.ptr<uchar>();
  std::vector<int> depth(size_t(w * h), 0);
  auto push_around = [&](int p) {
    const int px = p % w, py = p / w, lab = sv[p];
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int qx = px + dx, qy = py + dy;
        if (qx < 0 || qy < 0 || qx >= w || qy >= h) continue;
        const int q = qy * w + qx;
        if (pv[q] <= 0 || sv[q]) continue;
        if (bv[q]) queue.push({-(1000 + depth[size_t(p)] + 1), q * (n + 1) + lab});
        else queue.push({-std::abs(int(cv_[q]) - level[size_t(lab)]), q * (n + 1) + lab});
      }
  };
  for (int p = 0; p < w * h; ++p)
    if (sv[p]) push_around(p);
  while (!queue.empty()) {
    const int key = queue.top().first, q = queue.top().second / (n + 1), lab = queue.top().second % (n + 1);
    queue.pop();
    if (sv[q]) continue;
    sv[q] = lab;
    depth[size_t(q)] = key <= -1000 ? -key - 1000 : 0;
    push_around(q);
  }
  seeds.copyTo(parts);
}

}  // namespace rbx1::vision
