// isolate.cpp - binary image, cleaning, connected components (region growing) and the per-object soft layers.
#include "isolate.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

namespace rbx1::vision {
namespace {

// The object's contrast level: median over its interior, so the half level marks the true edge.
double object_level(const cv::Mat& c, const cv::Mat& comp, double threshold) {
  cv::Mat core;
  cv::erode(comp, core, cv::Mat(), cv::Point(-1, -1), 2);
  std::vector<float> v;
  v.reserve(size_t(c.total()));
  for (int y = 0; y < c.rows; ++y) {
    const float* cr = c.ptr<float>(y);
    const uchar* m = core.ptr<uchar>(y);
    for (int x = 0; x < c.cols; ++x)
      if (m[x]) v.push_back(cr[x]);
  }
  if (v.size() < 5) {
    double mx = threshold;
    cv::minMaxLoc(c, nullptr, &mx, nullptr, nullptr, comp);
    return std::max(mx, threshold);
  }
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return std::max<double>(v[v.size() / 2], threshold);
}

// Soft layer: 1 well inside, 0 well outside or on another object, contrast/level across the edge band.
void make_layer(const Contrast& con, const cv::Mat& labels, int label, cv::Rect roi, double threshold, Layer& layer) {
  cv::Mat lab = labels(roi);
  cv::Mat comp = lab == label;
  cv::Mat other = (lab != label) & (lab != 0);
  cv::Mat c;
  con.diff(roi).convertTo(c, CV_32F, con.sign);
  double level = object_level(c, comp, threshold);
  cv::Mat near;
  cv::dilate(comp, near, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7)));
  cv::Mat half = (c > level / 2) & near & ~other;
  cv::Mat interior, reach;
  cv::erode(half, interior, cv::Mat(), cv::Point(-1, -1), 2);
  cv::dilate(half, reach, cv::Mat(), cv::Point(-1, -1), 2);
  reach &= ~other;
  layer.soft.create(roi.size(), CV_32F);
  const float inv = float(1.0 / level);
  for (int y = 0; y < roi.height; ++y) {
    const float* cr = c.ptr<float>(y);
    const uchar* in = interior.ptr<uchar>(y);
    const uchar* re = reach.ptr<uchar>(y);
    float* s = layer.soft.ptr<float>(y);
    for (int x = 0; x < roi.width; ++x) s[x] = in[x] ? 1.f : (re[x] ? std::clamp(cr[x] * inv, 0.f, 1.f) : 0.f);
  }
  layer.inside = half;
  layer.roi = roi;
  layer.label = label;
}

}  // namespace

bool isolate(const Contrast& con, const IsolationOptions& opt, Isolation& out, std::string& error) {
  const cv::Mat& d = con.diff;
  out.threshold = std::max(opt.min_contrast, opt.noise_k * con.noise_sigma);
  cv::Mat bin;
  if (con.sign > 0) cv::compare(d, out.threshold, bin, cv::CMP_GT);
  else cv::compare(d, -out.threshold, bin, cv::CMP_LT);
  cv::morphologyEx(bin, bin, cv::MORPH_OPEN, cv::Mat());  // cleaning: isolated noise pixels and hairlines
  double fg = double(cv::countNonZero(bin)) / double(bin.total());
  if (fg > opt.max_foreground) {
    error = "frame is " + std::to_string(int(std::lround(fg * 100))) +
            "% foreground: wrong background image or polarity, or no table in view";
    return false;
  }
  cv::Mat stats, centroids;
  int n = cv::connectedComponentsWithStats(bin, out.labels, stats, centroids, 8, CV_32S);
  out.obstacle.assign(size_t(n), 0);
  struct Cand { int label; cv::Rect box; };
  std::vector<Cand> keep;
  for (int i = 1; i < n; ++i) {
    cv::Rect box(stats.at<int>(i, cv::CC_STAT_LEFT), stats.at<int>(i, cv::CC_STAT_TOP), stats.at<int>(i, cv::CC_STAT_WIDTH),
                 stats.at<int>(i, cv::CC_STAT_HEIGHT));
    int area = stats.at<int>(i, cv::CC_STAT_AREA);
    if (area < opt.min_area_px) {
      ++out.specks;
      continue;
    }
    out.obstacle[size_t(i)] = 1;
    if (box.x == 0 || box.y == 0 || box.br().x == d.cols || box.br().y == d.rows) {
      ++out.border;
      continue;
    }
    keep.push_back({i, box});
  }
  const cv::Rect frame(0, 0, d.cols, d.rows);
  auto grow = [&](cv::Rect box) {
    return cv::Rect(box.x - opt.margin_px, box.y - opt.margin_px, box.width + 2 * opt.margin_px,
                    box.height + 2 * opt.margin_px) & frame;
  };
  for (const Cand& k : keep) {
    Layer layer;
    make_layer(con, out.labels, k.label, grow(k.box), out.threshold, layer);
    // Near objects joined by their blurred edges at the low threshold come apart at the half level:
    // each piece big enough becomes an object of its own, with a new label.
    cv::Mat pl, ps, pc;
    int np = cv::connectedComponentsWithStats(layer.inside, pl, ps, pc, 8, CV_32S);
    std::vector<int> big;
    for (int p = 1; p < np; ++p)
      if (ps.at<int>(p, cv::CC_STAT_AREA) >= opt.min_area_px) big.push_back(p);
    if (big.size() <= 1) {
      if (cv::countNonZero(layer.inside) < opt.min_area_px) {
        ++out.specks;
        continue;
      }
      out.layers.push_back(std::move(layer));
      continue;
    }
    for (int p : big) {
      int id = int(out.obstacle.size());
      out.obstacle.push_back(1);
      cv::Mat lab = out.labels(layer.roi);
      lab.setTo(id, (pl == p) & (lab == k.label));
      cv::Rect box(ps.at<int>(p, cv::CC_STAT_LEFT) + layer.roi.x, ps.at<int>(p, cv::CC_STAT_TOP) + layer.roi.y,
                   ps.at<int>(p, cv::CC_STAT_WIDTH), ps.at<int>(p, cv::CC_STAT_HEIGHT));
      Layer piece;
      make_layer(con, out.labels, id, grow(box), out.threshold, piece);
      if (cv::countNonZero(piece.inside) >= opt.min_area_px) out.layers.push_back(std::move(piece));
    }
  }
  // Detection order: by rows of the top edge, then left to right (split pieces included).
  std::stable_sort(out.layers.begin(), out.layers.end(), [](const Layer& a, const Layer& b) {
    return a.roi.y != b.roi.y ? a.roi.y < b.roi.y : a.roi.x < b.roi.x;
  });
  return true;
}

}  // namespace rbx1::vision
