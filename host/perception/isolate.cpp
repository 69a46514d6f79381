// isolate.cpp - binary image, cleaning, connected components (region growing) and the per-object soft layers.
#include "isolate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "avx2_clones.hpp"
#include "components.hpp"
#include "pixels.hpp"

namespace rbx1::vision {
namespace {

// Otsu's cut over hist[from..to]: the last bin of the darker (lower) class; from - 1 when there is none.
int otsu_cut(const int* hist, int from, int to) {
  double n = 0, sum = 0;
  for (int i = from; i <= to; ++i) n += hist[i], sum += double(i) * hist[i];
  double best = -1, w0 = 0, s0 = 0;
  int cut = from - 1;
  for (int k = from; k < to; ++k) {
    w0 += hist[k], s0 += double(k) * hist[k];
    const double w1 = n - w0;
    if (w0 < 1 || w1 < 1) continue;
    const double m0 = s0 / w0, m1 = (sum - s0) / w1, between = w0 * w1 * (m1 - m0) * (m1 - m0);
    if (between > best) best = between, cut = k;
  }
  return cut;
}

// The median bin of hist[from..to].
int median_of(const int* hist, int from, int to) {
  double n = 0;
  for (int i = from; i <= to; ++i) n += hist[i];
  int m = from;
  for (double acc = 0; m < to && (acc += hist[m]) * 2 < n; ++m) {}
  return m;
}

// The lighter class of a region, lo < c <= hi (`cand`), opened 5x5 (a blurred rim or a specular streak is thinner;
// an erosion as the dilation of the complement: outside the ROI counts as set, as cv::erode's default border has
// it) and regrown 2 px within itself (`grown`). Returns whether anything is left.
bool lighter_class(const uchar* cbuf, const uchar* obuf, int W, int H, uchar lo, uchar hi, cv::Mat& cand,
                   cv::Mat& grown) {
  cand.create(H, W, CV_8U);
  for (int y = 0; y < H; ++y) {
    const uchar* cr = cbuf + size_t(y) * size_t(W);
    const uchar* orow = obuf + size_t(y) * size_t(W);
    uchar* a = cand.ptr<uchar>(y);
    for (int x = 0; x < W; ++x) a[x] = orow[x] & uchar(-int(cr[x] > lo)) & uchar(-int(cr[x] <= hi));
  }
  cv::Mat opened;
  cv::bitwise_not(cand, grown);
  dilate_square(grown, opened, 2);
  cv::bitwise_not(opened, opened);
  dilate_square(opened, opened, 2);
  if (cv::countNonZero(opened) == 0) {
    grown.setTo(0);
    return false;
  }
  dilate_square(opened, grown, 2);
  grown &= cand;
  return true;
}

// Within 2 px of the shade the contrast taken against the shade instead of the table, c' = (c - s) L / (L - s)
// (s: the shade's median, L: the object's level): the shade has none and the object's edge over it lies
// half-way between shade and object, as its edge over the table does. Returns whether cbuf changed.
bool against_shade(uchar* cbuf, int W, int H, const cv::Mat& shade, int L) {
  int sh[256] = {}, ns = 0;
  for (int y = 0; y < H; ++y) {
    const uchar* cr = cbuf + size_t(y) * size_t(W);
    const uchar* m = shade.ptr<uchar>(y);
    for (int x = 0; x < W; ++x)
      if (m[x]) sh[cr[x]]++, ++ns;
  }
  int s = 0;
  for (int acc = 0; s < 256 && (acc += sh[s]) * 2 < ns; ++s) {}
  if (L - s < 1) return false;
  cv::Mat zone;
  dilate_square(shade, zone, 2);
  const double k = double(L) / double(L - s);
  for (int y = 0; y < H; ++y) {
    uchar* cr = cbuf + size_t(y) * size_t(W);
    const uchar* z = zone.ptr<uchar>(y);
    for (int x = 0; x < W; ++x)
      if (z[x]) cr[x] = uchar(std::clamp(int(std::lround((cr[x] - s) * k)), 0, 255));
  }
  return true;
}

// Without a captured background, an object's own soft shadow beside one side has no model of the shaded table:
// it is a shelf of contrast between the object's half level and its own level, attached to the object and
// reaching out to the table (stuff.jpg's black cap: 75-90 levels of shade beside 110 of cap, on one side).
// Among the component's pixels above the half level Otsu's cut parts a lighter class from the object's; when
// the classes lie far apart (4 noise sigma and a fifth of the object's class) and the lighter one is no larger,
// the lighter class opened 5x5 (a blurred rim, a specular streak or texture are thinner) and regrown 2 px within
// itself gives pieces; a piece no larger than the object's class whose 1 px ring is at least 10 % the object's
// class (against its caster) and at least 10 % outside the half level (reaching the table), at least a tenth of
// the object's class, and soft (the component's band below the half level beyond it at least twice as deep as
// beyond the object's own edge away from it: a penumbra, not the camera's blur; a sweet's lit half has the
// sweet's sharp edge) is shade, and near it the contrast is taken against it (against_shade). Returns whether
// shade was found (cbuf changed).
bool drop_shade_shelf(uchar* cbuf, const uchar* obuf, int W, int H, const int* hist, int half_c, double sigma) {
  double n = 0, sum = 0;
  for (int i = half_c + 1; i < 256; ++i) n += hist[i], sum += double(i) * hist[i];
  if (n < 50) return false;
  const int cut = otsu_cut(hist, half_c + 1, 255);
  if (cut <= half_c) return false;
  double n_lo = 0, s_lo = 0;
  for (int i = half_c + 1; i <= cut; ++i) n_lo += hist[i], s_lo += double(i) * hist[i];
  const double n_hi = n - n_lo, m_lo = s_lo / n_lo, m_hi = (sum - s_lo) / n_hi;
  if (m_hi - m_lo < std::max(4 * sigma, 0.2 * m_hi) || n_lo > n_hi || n_lo < 0.1 * n_hi) return false;
  // Most objects stop here: their blurred rim is all the lighter class has.
  cv::Mat cand, grown;
  if (!lighter_class(cbuf, obuf, W, H, uchar(half_c), uchar(cut), cand, grown)) return false;
  const uchar lo = uchar(half_c), hi = uchar(cut);
  cv::Mat core(H, W, CV_8U), outside(H, W, CV_8U), band(H, W, CV_8U);
  for (int y = 0; y < H; ++y) {
    const uchar* cr = cbuf + size_t(y) * size_t(W);
    const uchar* orow = obuf + size_t(y) * size_t(W);
    uchar* b = core.ptr<uchar>(y);
    uchar* o = outside.ptr<uchar>(y);
    uchar* bd = band.ptr<uchar>(y);
    for (int x = 0; x < W; ++x) {
      const uchar above = uchar(-int(cr[x] > lo));
      bd[x] = orow[x] & ~above;
      b[x] = orow[x] & uchar(-int(cr[x] > hi));
      o[x] = uchar(~orow[x] | ~above);
    }
  }
  cv::Mat pieces, stats, centres;
  const int np = cv::connectedComponentsWithStats(grown, pieces, stats, centres, 8, CV_32S);
  cv::Mat shade(H, W, CV_8U, cv::Scalar(0));
  bool any = false;
  for (int p = 1; p < np; ++p) {
    const int area = stats.at<int>(p, cv::CC_STAT_AREA);
    if (area > n_hi || area < 0.1 * n_hi) continue;
    cv::Mat piece = pieces == p, ring;
    dilate_square(piece, ring, 1);
    ring &= ~piece;
    const int n_ring = cv::countNonZero(ring);
    if (n_ring == 0) continue;
    const int n_out = cv::countNonZero(ring & outside);
    if (cv::countNonZero(ring & core) < 0.1 * n_ring || n_out < 0.1 * n_ring) continue;
    // Soft: the component's band below the half level is deeper beyond the piece than beyond the object's own
    // edge elsewhere (a shadow's penumbra against the camera's blur). Depth: the band within 8 px over the band
    // within 1 px.
    cv::Mat m1, m8, far_p, half_region = cand | core;
    dilate_square(piece, m1, 1);
    dilate_square(piece, m8, 8);
    const double w_piece = double(cv::countNonZero(m8 & band)) / std::max(1, cv::countNonZero(m1 & band));
    dilate_square(m8, far_p, 8);
    dilate_square(half_region, m1, 1);
    dilate_square(half_region, m8, 8);
    const int n_c1 = cv::countNonZero(m1 & band & ~far_p);
    const double w_core = double(cv::countNonZero(m8 & band & ~far_p)) / std::max(1, n_c1);
    if (n_c1 == 0 || w_piece < 2 * w_core) continue;  // no free edge to compare with, or not soft
    shade |= piece;
    any = true;
  }
  if (!any) return false;
  return against_shade(cbuf, W, H, shade, median_of(hist, cut + 1, 255));
}

// The blur of an edge of height h: the contrast's gradient is steepest where it crosses h/2, h / (sigma sqrt(2 pi))
// for a step blurred by a Gaussian; the median gradient over the pixels of `where` between 0.4 h and 0.6 h.
// Returns 0 when there are none (noise only steepens the gradient: a noisy edge looks sharper, never softer).
double edge_blur(const cv::Mat& contrast, const cv::Mat& where, double h) {
  cv::Mat gx, gy;
  cv::Sobel(contrast, gx, CV_32F, 1, 0, 3, 1.0 / 8);
  cv::Sobel(contrast, gy, CV_32F, 0, 1, 3, 1.0 / 8);
  std::vector<float> g;
  for (int y = 0; y < contrast.rows; ++y)
    for (int x = 0; x < contrast.cols; ++x) {
      const int c = contrast.at<uchar>(y, x);
      if (where.at<uchar>(y, x) && c > 0.4 * h && c < 0.6 * h)
        g.push_back(std::hypot(gx.at<float>(y, x), gy.at<float>(y, x)));
    }
  if (g.size() < 20) return 0;
  std::nth_element(g.begin(), g.begin() + long(g.size() / 2), g.end());
  const double m = g[g.size() / 2];
  return m > 0 ? h / (std::sqrt(2 * M_PI) * m) : 0;
}

// A thin dark caster (a star's arms) can have a soft shadow as large as itself or larger: the region's median
// contrast is then the shade's, not the object's, and the half level lets shade into the outline (tools/world's
// sil_star_2 seen from above: 7202 px of shade at contrast 16-86 beside 5929 px of star at 143; median 30,
// area 12915 px for about 6000). Otsu's cut over the whole region parts the two; when the median `med` falls in
// the lighter class, the darker class is the caster and its median L the object's level, if the lighter class
// lies under L/2 (at the caster's level it is a shadow fainter than half the object, which the layer leaves out
// anyway) and its edge towards the table is at least 1.5 times as blurred as the caster's (a penumbra against
// the camera's blur: 2.2 px against 1.2 there; a grey part of a two-tone object has the object's own sharp edge).
// Then near the shade (the lighter class opened, without the caster's blurred rim) the contrast is taken against
// it, as drop_shade_shelf does, so the shade does not widen the caster's long edge over it. Returns L (cbuf may
// have changed), or 0.
int caster_level(uchar* cbuf, const uchar* obuf, int W, int H, const int* hist, int med, double sigma) {
  const int cut = otsu_cut(hist, 1, 255);
  if (med > cut) return 0;  // the median is the object's own: the usual case
  double n_hi = 0;
  for (int i = cut + 1; i < 256; ++i) n_hi += hist[i];
  if (n_hi < 50) return 0;
  const int s = median_of(hist, 1, cut), L = median_of(hist, cut + 1, 255);
  if (L - s < std::max(4 * sigma, 0.2 * L) || 2 * s >= L) return 0;
  const cv::Mat contrast(H, W, CV_8U, cbuf), own(H, W, CV_8U, const_cast<uchar*>(obuf));
  // Each edge away from the other: the shade's (fading below the region's threshold) beyond 3 px of the caster,
  // the caster's beyond 3 px of the shade (over the shade its ramp is lower and mixes with the shade's levels).
  cv::Mat near, cand, lighter, by_shade, by_caster;
  dilate_square(own, near, 3);
  dilate_square(own & (contrast > cut), by_caster, 3);
  const bool body = lighter_class(cbuf, obuf, W, H, 0, uchar(cut), cand, lighter);
  dilate_square(lighter, by_shade, 3);
  const double shade = edge_blur(contrast, near & ~by_caster, s), object = edge_blur(contrast, own & ~by_shade, L);
  if (shade <= 0 || object <= 0 || shade < 1.5 * object) return 0;
  if (body) against_shade(cbuf, W, H, lighter, L);
  return L;
}

// The automatic background's global surface is one quadratic over the whole table: a cloth whose level drifts
// locally (folds, vignetting) can lie well away from it beside one object (coins.png: cloth 105 under a surface
// of 120), and an object's faint relief then falls below the low threshold, denting its outline. The table's
// own level beside the object: the median contrast (in the object's polarity) over the unlabelled pixels 3 to
// 8 px outside the component's box. When it lies on the far side of the surface by over a quarter of the low
// threshold (and 4 levels), the component is regrown by hysteresis against that level (unlabelled pixels above
// the low threshold, connected to it, within a window of a quarter of its size, at least 8 px, around it; the
// labels and box follow) and the level is returned, to be taken off the object's contrast; otherwise 0. A
// regrowth reaching the window's edge (the table itself above the low threshold against that level, or the
// frame's edge) is not kept.
int local_table(const Contrast& con, cv::Mat& labels, int label, int sign, double low, cv::Rect& box) {
  if (!con.global_model || sign == 0) return 0;
  const cv::Rect frame(0, 0, labels.cols, labels.rows);
  // The ring: the unlabelled pixels of a frame 3 to 8 px outside the component's box (its corners are table
  // too, a few px further out on a round object).
  const cv::Rect q = cv::Rect(box.x - 8, box.y - 8, box.width + 16, box.height + 16) & frame;
  const int x0 = box.x - 2, x1 = box.br().x + 2, y0 = box.y - 2, y1 = box.br().y + 2;
  int hist[511] = {}, n = 0;
  for (int y = q.y; y < q.br().y; ++y) {
    const int* lr = labels.ptr<int>(y);
    const uchar *gr = con.gray.ptr<uchar>(y), *br = con.background.ptr<uchar>(y);
    const bool band = y < y0 || y >= y1;
    for (int x = q.x; x < q.br().x; ++x) {
      if (!band && x >= x0 && x < x1) x = x1 - 1;  // the box and its 2 px margin
      else if (lr[x] == 0) hist[255 + sign * (int(gr[x]) - int(br[x]))]++, ++n;
    }
  }
  if (n < 20) return 0;
  int t = 0;
  for (int acc = 0; t < 511 && (acc += hist[t]) * 2 < n; ++t) {}
  const int table = t - 255;
  if (-table <= std::max(0.25 * low, 4.0)) return 0;
  const int m = std::max(8, std::max(box.width, box.height) / 4);
  const cv::Rect r = cv::Rect(box.x - m, box.y - m, box.width + 2 * m, box.height + 2 * m) & frame;
  const cv::Mat lab = labels(r), g = con.gray(r), bg = con.background(r);
  // Hysteresis against the local level: the component and the unlabelled pixels above the low threshold.
  cv::Mat cand(r.size(), CV_8U), comp;
  for (int y = 0; y < r.height; ++y) {
    const int* lr = lab.ptr<int>(y);
    const uchar *gr = g.ptr<uchar>(y), *br = bg.ptr<uchar>(y);
    uchar* c = cand.ptr<uchar>(y);
    for (int x = 0; x < r.width; ++x)
      c[x] = uchar(lr[x] == label || (lr[x] == 0 && sign * (int(gr[x]) - int(br[x])) - table > low));
  }
  const int nc = cv::connectedComponents(cand, comp, 8, CV_32S);
  std::vector<char> keep(size_t(nc), 0);
  for (int y = 0; y < r.height; ++y) {
    const int* lr = lab.ptr<int>(y);
    const int* cr = comp.ptr<int>(y);
    for (int x = 0; x < r.width; ++x)
      if (lr[x] == label) keep[size_t(cr[x])] = 1;
  }
  cv::Mat grown(r.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < r.height; ++y) {
    const int* cr = comp.ptr<int>(y);
    uchar* gw = grown.ptr<uchar>(y);
    for (int x = 0; x < r.width; ++x) gw[x] = uchar(-int(cr[x] > 0 && keep[size_t(cr[x])]));
  }
  const cv::Rect gb = cv::boundingRect(grown);
  if (gb.x == 0 || gb.y == 0 || gb.br().x == r.width || gb.br().y == r.height) return 0;
  cv::Mat lw = labels(r);
  lw.setTo(label, grown);
  label_frame_written(labels, r);
  box = (gb + r.tl()) | box;
  return table;
}

// A shaded object (lit from one side: its contrast falls smoothly across it, issue 27) has a darker side below
// its half level, which the object's one level would leave out of its outline (and a finger's contact inside
// the material). Shaded: at least 10 of the component's deep pixels (3 px and more inside its outline) lie at or
// below the half level, and the contrast where they meet the deep pixels above it rises gently (median Sobel
// gradient under 5 % of the level per px): a ramp, not the step to a cast shadow, a fainter neighbour or a
// two-tone part (a step's gradient is its height over the blur's width: a third of the level and more). Then
// each pixel's level is the deep pixels' contrast around it (Gaussian-weighted, sigma 3 px, then 12 px, the
// object's median where none lie near), at least max(12, 4 sigma), and the half level is half of it: the edge half-way between
// the table and the object just inside it, as on a flat object. Returns false (local untouched) otherwise.
bool shaded_level(const uchar* cbuf, const uchar* obuf, int W, int H, double level, int half_c, double sigma,
                  cv::Mat& local) {
  const cv::Mat c(H, W, CV_8U, const_cast<uchar*>(cbuf)), own(H, W, CV_8U, const_cast<uchar*>(obuf));
  cv::Mat deep;
  cv::erode(own, deep, cv::Mat(), cv::Point(-1, -1), 3, cv::BORDER_CONSTANT, cv::Scalar(0));
  int n_deep = 0, n_low = 0;
  for (int y = 0; y < H; ++y) {
    const uchar* d = deep.ptr<uchar>(y);
    const uchar* cr = c.ptr<uchar>(y);
    for (int x = 0; x < W; ++x)
      if (d[x]) ++n_deep, n_low += cr[x] <= half_c;
  }
  if (n_low < 10) return false;
  std::vector<float> grad;
  for (int y = 1; y + 1 < H; ++y) {
    const uchar *d = deep.ptr<uchar>(y), *du = deep.ptr<uchar>(y - 1), *dd = deep.ptr<uchar>(y + 1);
    const uchar *cr = c.ptr<uchar>(y), *cu = c.ptr<uchar>(y - 1), *cd = c.ptr<uchar>(y + 1);
    for (int x = 1; x + 1 < W; ++x) {
      if (!d[x] || cr[x] > half_c) continue;
      const bool meets = (d[x - 1] && cr[x - 1] > half_c) || (d[x + 1] && cr[x + 1] > half_c) ||
                         (du[x] && cu[x] > half_c) || (dd[x] && cd[x] > half_c);
      if (!meets) continue;
      const float gx = float(cu[x + 1] + 2 * cr[x + 1] + cd[x + 1] - cu[x - 1] - 2 * cr[x - 1] - cd[x - 1]) / 8.f;
      const float gy = float(cd[x - 1] + 2 * cd[x] + cd[x + 1] - cu[x - 1] - 2 * cu[x] - cu[x + 1]) / 8.f;
      grad.push_back(std::hypot(gx, gy));
    }
  }
  if (grad.size() < 5) return false;
  std::nth_element(grad.begin(), grad.begin() + long(grad.size() / 2), grad.end());
  if (grad[grad.size() / 2] >= 0.05 * level) return false;
  cv::Mat w, cw, num, den;
  deep.convertTo(w, CV_32F, 1.0 / 255);
  c.convertTo(cw, CV_32F);
  cw = cw.mul(w);
  // Near the deep pixels their contrast within 3 px; further out (a star's points, a T's stem on the dark side)
  // within 12 px; the object's median only where neither reaches.
  const float eps = 0.01f, floor_level = float(std::max(12.0, 4 * sigma));
  cv::GaussianBlur(cw, num, cv::Size(), 12.0, 12.0, cv::BORDER_CONSTANT);
  cv::GaussianBlur(w, den, cv::Size(), 12.0, 12.0, cv::BORDER_CONSTANT);
  const cv::Mat wide = (num + eps * float(level)) / (den + eps);
  cv::GaussianBlur(cw, num, cv::Size(), 3.0, 3.0, cv::BORDER_CONSTANT);
  cv::GaussianBlur(w, den, cv::Size(), 3.0, 3.0, cv::BORDER_CONSTANT);
  local = (num + eps * wide) / (den + eps);
  local = cv::max(local, floor_level);
  return true;
}

// One row of the contrast against the table, 8-bit and saturated at 0: sign * (gray - background) - table for a
// polarity (the local table's level taken off), |gray - background| for a two-colour object (sign 0, no table).
// Inline, so that it runs in the AVX2 clone of its caller.
inline void contrast_row(const uchar* gr, const uchar* br, int sign, int table, int W, uchar* cr) {
  if (sign != 0 && table == 0) {  // the saturated difference as a byte max and subtraction
    const uchar* hi = sign > 0 ? gr : br;
    const uchar* lo = sign > 0 ? br : gr;
    for (int x = 0; x < W; ++x) cr[x] = uchar(std::max(hi[x], lo[x]) - lo[x]);
  } else if (sign > 0) {
    for (int x = 0; x < W; ++x) cr[x] = uchar(std::clamp(int(gr[x]) - int(br[x]) - table, 0, 255));
  } else if (sign < 0) {
    for (int x = 0; x < W; ++x) cr[x] = uchar(std::clamp(int(br[x]) - int(gr[x]) - table, 0, 255));
  } else {
    for (int x = 0; x < W; ++x) cr[x] = uchar(std::abs(int(gr[x]) - int(br[x])));
  }
}

// The object's own contrast where a faint shade joined its component: the median over the pixels at or above
// half of the plain median `med`, when they are of one tone (their quartiles within a quarter of that median).
// A cast shadow above the low threshold joins a thin part's component and pulls the plain median down (a ring
// 20 px wide, light grey: 90 against its own pixels' 117, quartiles 116-118), which put its half level, so its
// outline, out in the blur: the same part measured 4 % larger light grey than black. A part of several tones
// (smarties.png's orange sweet, highlight and shading: quartiles 75-179) keeps the plain median.
int own_level(const int* hist, int med) {
  const int from = (med + 1) / 2;
  int above = 0;
  for (int i = from; i < 256; ++i) above += hist[i];
  if (above == 0) return med;
  auto quantile = [&](int q) {  // the q-th quarter of the pixels above `from`
    int i = from;
    for (int acc = 0; i < 255 && (acc += hist[i]) * 4 < q * above; ++i) {}
    return i;
  };
  const int own = quantile(2);
  return quantile(3) - quantile(1) <= own / 4 ? own : med;
}

// Soft layer of one component in one fused pass: s = (c - lo) / (hi - lo) clamped, with lo = 2 sigma and
// hi = level - 2 sigma around the object's contrast level (median over its pixels), so noise leaves the
// interior at 1 and the table at 0 while the anti-aliased edge keeps its covered fraction (half level =
// level / 2). Pixels of other objects are 0.
// (The byte loops take 32 pixels at a time where the CPU has AVX2, as in components.cpp; no fused multiply-adds.)
RBX1_AVX2_CLONES
void make_layer(const Contrast& con, const cv::Mat& labels, int label, int sign, cv::Rect roi, double threshold,
                Layer& layer, bool shade_shelf = false, int table = 0) {
  const cv::Mat lab = labels(roi), g = con.gray(roi), bg = con.background(roi);
  const int W = roi.width, H = roi.height;
  layer.sign = sign;
  // The contrast over the ROI, computed once, 8-bit and saturated at 0: the component's pixels all lie above
  // the low threshold (the opening only lowers the contrast), and the layer clamps at 0 anyway. The
  // component's mask beside it, and the median contrast over the component (histograms by column mod 4, so
  // that equal neighbours do not wait on each other's count).
  thread_local std::vector<uchar> cbuf, obuf, zbuf;  // contrast, own pixels, unlabelled pixels
  cbuf.resize(size_t(roi.area()));
  obuf.resize(size_t(roi.area()));
  zbuf.resize(size_t(roi.area()));
  int hist4[4][256] = {};
  int n = 0;
  for (int y = 0; y < H; ++y) {
    const uchar* gr = g.ptr<uchar>(y);
    const uchar* br = bg.ptr<uchar>(y);
    const int* lr = lab.ptr<int>(y);
    uchar* cr = cbuf.data() + size_t(y) * size_t(W);
    uchar* orow = obuf.data() + size_t(y) * size_t(W);
    uchar* zrow = zbuf.data() + size_t(y) * size_t(W);
    contrast_row(gr, br, sign, table, W, cr);
    for (int x = 0; x < W; ++x) orow[x] = uchar(-int(lr[x] == label));
    for (int x = 0; x < W; ++x) zrow[x] = uchar(-int(lr[x] == 0));
    int row_n = 0;
    for (int x = 0; x < W; ++x) row_n += orow[x] & 1;
    n += row_n;
    // 8 pixels at a time: none of the component's (the ROI's corners and margin) counts only in bin 0.
    int x = 0;
    for (; x + 8 <= W; x += 8) {
      uint64_t any;
      std::memcpy(&any, orow + x, 8);
      if (any)
        for (int k = 0; k < 8; ++k) hist4[k & 3][cr[x + k] & orow[x + k]]++;
    }
    for (; x < W; ++x) hist4[x & 3][cr[x] & orow[x]]++;
  }
  int hist[256];
  for (int i = 0; i < 256; ++i) hist[i] = hist4[0][i] + hist4[1][i] + hist4[2][i] + hist4[3][i];
  hist[0] = n;  // bin 0 also counted the pixels outside the component
  for (int i = 1; i < 256; ++i) hist[0] -= hist[i];
  auto median = [&] {
    int acc = 0;
    for (int i = 0; i < 256; ++i)
      if ((acc += hist[i]) * 2 >= n) return i;
    return 0;
  };
  int med = median();
  auto half_of = [&](int m) { return int(std::floor(std::max<double>(m, threshold) / 2)); };
  auto recount = [&] {  // the contrast changed near the shade
    std::fill(hist, hist + 256, 0);
    for (size_t i = 0; i < cbuf.size(); ++i)
      if (obuf[i]) hist[cbuf[i]]++;
  };
  // A shade larger than its caster: the caster's level, not the region's median (which is the shade's).
  const bool dark_shade = shade_shelf && sign < 0;
  const int caster = dark_shade ? caster_level(cbuf.data(), obuf.data(), W, H, hist, med, con.noise_sigma) : 0;
  if (caster > 0) recount(), med = caster;
  if (dark_shade && drop_shade_shelf(cbuf.data(), obuf.data(), W, H, hist, half_of(med), con.noise_sigma)) {
    recount();  // the component's median again (the caster's: above its half level)
    med = caster > 0 ? median_of(hist, half_of(caster) + 1, 255) : median();
  }
  med = own_level(hist, med);
  const double level = std::max<double>(med, threshold);
  layer.level = level;
  const double lo = std::min(2 * con.noise_sigma, level * 0.25), hi = std::max(level - 2 * con.noise_sigma, level * 0.75);
  const float a = float(1.0 / (hi - lo)), b = float(-lo / (hi - lo)), half = float(level / 2);
  // The object at its half level, then the soft edge within 2 px of it: a shadow or glare joined to the
  // object at the low threshold, but fainter than half its contrast, stays out of the moments.
  // (An integer contrast c is above the half level exactly when it is above its floor.)
  const uchar half_c = uchar(std::min(int(std::floor(half)), 255));
  cv::Mat local;  // per-pixel level of a shaded object; empty for a flat one (the usual case)
  const bool shaded = sign > 0 && shaded_level(cbuf.data(), obuf.data(), W, H, level, half_c, con.noise_sigma, local);
  layer.inside.create(roi.size(), CV_8U);
  for (int y = 0; y < H; ++y) {
    const uchar* cr = cbuf.data() + size_t(y) * size_t(W);
    const uchar* orow = obuf.data() + size_t(y) * size_t(W);
    uchar* ir = layer.inside.ptr<uchar>(y);
    if (shaded) {
      const float* lr = local.ptr<float>(y);
      for (int x = 0; x < W; ++x) ir[x] = orow[x] & uchar(-int(float(cr[x]) > lr[x] / 2));
    } else {
      for (int x = 0; x < W; ++x) ir[x] = orow[x] & uchar(-int(cr[x] > half_c));
    }
  }
  cv::Mat near;
  dilate_square(layer.inside, near, 2);
  // The ramp, computed per pixel 8 at a time (a table lookup cannot be); contrast 0 is also every pixel left out.
  layer.soft.create(roi.size(), CV_32F);
  for (int y = 0; y < H; ++y) {
    const uchar* cr = cbuf.data() + size_t(y) * size_t(W);
    const uchar* orow = obuf.data() + size_t(y) * size_t(W);
    const uchar* zrow = zbuf.data() + size_t(y) * size_t(W);
    const uchar* nr = near.ptr<uchar>(y);
    float* sr = layer.soft.ptr<float>(y);
    if (shaded) {  // the same ramp about each pixel's own level
      const float* lr = local.ptr<float>(y);
      const float ns = float(2 * con.noise_sigma);
      for (int x = 0; x < W; ++x) {
        const float l = lr[x], lo_l = std::min(ns, 0.25f * l), hi_l = std::max(l - ns, 0.75f * l);
        sr[x] = std::clamp((float(cr[x] & nr[x] & (orow[x] | zrow[x])) - lo_l) / (hi_l - lo_l), 0.f, 1.f);
      }
      continue;
    }
    for (int x = 0; x < W; ++x) sr[x] = std::clamp(float(cr[x] & nr[x] & (orow[x] | zrow[x])) * a + b, 0.f, 1.f);
  }
  layer.roi = roi;
  layer.label = label;
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(layer.inside, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  layer.outer.clear();
  for (auto& c : contours) {
    double area = cv::contourArea(c);
    if (area >= 1) layer.pieces.push_back({area, std::move(c)});
  }
  std::sort(layer.pieces.begin(), layer.pieces.end(), [](const auto& p, const auto& q) { return p.first > q.first; });
  if (!layer.pieces.empty()) layer.outer = layer.pieces.front().second;
}

// Both polarities: a region whose surroundings (a 3 px ring) are mostly an object of the other polarity is a
// detail of that object (the dark relief on a light coin); a region attached to an object of the other
// polarity with fringe_ratio times its contrast is that object's shadow or glare (a white ball's shadow on a
// grey table). Neither is an object, nor an obstacle for the fingers.
// Then two regions of opposite polarity sharing a long boundary (at least 15 % of the smaller one's ring) are
// one object of two colours (a lighter's pink body and metal cap): merged, its layer on |frame - background|.
// Either polarity: a small region attached to an object of its own polarity with fringe_ratio times its
// contrast, at most a quarter of that object's area, is that object's soft shadow (the shade between two sweets
// on a white table), not an object: a shadow is darker than the table but far lighter than a dark object.
RBX1_AVX2_CLONES
void drop_fringes(const Contrast& con, const IsolationOptions& opt, Isolation& out) {
  std::vector<double> level(out.sign.size(), 0), area(out.sign.size(), 0);
  for (const Layer& l : out.layers) level[size_t(l.label)] = l.level, area[size_t(l.label)] = cv::countNonZero(l.inside);
  std::vector<char> drop(out.layers.size(), 0);
  std::vector<std::vector<int>> partner(out.layers.size());
  const cv::Rect frame(0, 0, out.labels.cols, out.labels.rows);
  for (size_t i = 0; i < out.layers.size(); ++i) {
    const Layer& l = out.layers[i];
    cv::Rect r = cv::Rect(l.roi.x - 3, l.roi.y - 3, l.roi.width + 6, l.roi.height + 6) & frame;
    cv::Mat lab = out.labels(r), own(r.size(), CV_8U), ring;
    // (Locals: byte stores may alias anything else, which would stop the loop vectorising.)
    const int label = l.label, rw = r.width;
    for (int y = 0; y < r.height; ++y) {
      const int* lr = lab.ptr<int>(y);
      uchar* o = own.ptr<uchar>(y);
      for (int x = 0; x < rw; ++x) o[x] = uchar(-int(lr[x] == label));
    }
    dilate_square(own, ring, 3);  // the 3 px ring: the dilation without the region itself
    int n_ring = 0, n_other = 0;
    double strongest = 0;
    bool shade = false;  // beside a far stronger, far larger object of its own polarity
    std::map<int, int> shared;  // opposite-polarity label -> ring pixels
    for (int y = 0; y < r.height; ++y) {
      const int* lr = lab.ptr<int>(y);
      uchar* rr = ring.ptr<uchar>(y);
      const uchar* ow = own.ptr<uchar>(y);
      for (int x = 0; x < rw; ++x) rr[x] &= uchar(~ow[x]);
      // The ring is a thin band: 8 pixels at a time are skipped while none is in it.
      for (int x = 0; x < rw; ++x) {
        if ((x & 7) == 0 && x + 8 <= rw) {
          uint64_t v;
          std::memcpy(&v, rr + x, 8);
          if (!v) {
            x += 7;
            continue;
          }
        }
        if (!rr[x]) continue;
        ++n_ring;
        int o = lr[x];
        if (o > 0 && o != l.label && out.sign[size_t(o)] == l.sign)
          shade = shade || (level[size_t(o)] >= opt.fringe_ratio * l.level && area[size_t(l.label)] <= 0.25 * area[size_t(o)]);
        if (o <= 0 || out.sign[size_t(o)] == l.sign) continue;
        ++shared[o];
        strongest = std::max(strongest, level[size_t(o)]);
        // A far fainter neighbour of the other polarity is this object's own shadow or glare (a light
        // part's dark cast shadow can wrap half its outline): it does not make this a detail of it.
        n_other += opt.fringe_ratio * level[size_t(o)] > l.level;
      }
    }
    drop[i] = n_other >= 0.4 * n_ring || (n_other > 0 && strongest >= opt.fringe_ratio * l.level) || shade;
    for (auto [o, n] : shared)
      if (n >= 0.15 * n_ring) partner[i].push_back(o);
  }
  // Merge the two-colour objects (union-find over layer indices, by label).
  std::map<int, size_t> index_of;
  for (size_t i = 0; i < out.layers.size(); ++i) index_of[out.layers[i].label] = i;
  std::vector<size_t> root(out.layers.size());
  for (size_t i = 0; i < root.size(); ++i) root[i] = i;
  auto find = [&](size_t i) {
    while (root[i] != i) i = root[i] = root[root[i]];
    return i;
  };
  for (size_t i = 0; i < out.layers.size(); ++i) {
    if (drop[i]) continue;
    for (int o : partner[i]) {
      auto it = index_of.find(o);
      if (it == index_of.end() || drop[it->second]) continue;
      size_t a = find(i), b = find(it->second);
      if (a != b) root[std::max(a, b)] = std::min(a, b);
    }
  }
  const cv::Rect frame_all(0, 0, out.labels.cols, out.labels.rows);
  for (size_t i = 0; i < out.layers.size(); ++i) {
    if (drop[i] || find(i) != i) continue;
    std::vector<size_t> members;
    for (size_t j = 0; j < out.layers.size(); ++j)
      if (!drop[j] && find(j) == i) members.push_back(j);
    if (members.size() < 2) continue;
    const int label = out.layers[i].label;
    cv::Rect box = out.layers[i].roi;
    for (size_t j : members) {
      if (j == i) continue;
      const Layer& m = out.layers[j];
      cv::Mat lab = out.labels(m.roi);
      lab.setTo(label, lab == m.label);
      out.obstacle[size_t(m.label)] = 0;
      box |= m.roi;
      drop[j] = 2;  // merged into i
    }
    Layer merged;
    make_layer(con, out.labels, label, 0, box & frame_all, out.threshold, merged);
    merged.pieces.clear();
    out.layers[i] = std::move(merged);
  }
  std::vector<Layer> kept;
  for (size_t i = 0; i < out.layers.size(); ++i) {
    if (drop[i] == 1) {
      ++out.fringes;
      out.obstacle[size_t(out.layers[i].label)] = 0;
    } else if (!drop[i]) {
      kept.push_back(std::move(out.layers[i]));
    }
  }
  out.layers = std::move(kept);
}

}  // namespace

namespace {

// Whether a layer's half-level region reaches the frame's edge: the object itself is cut by it. Its region at
// the low threshold may reach the edge by its faint blurred rim alone (an object 1 px from the edge, issue 27).
bool inside_at_edge(const Layer& layer, cv::Size frame) {
  const cv::Mat& in = layer.inside;
  const cv::Rect r = layer.roi;
  return (r.x == 0 && cv::countNonZero(in.col(0))) || (r.y == 0 && cv::countNonZero(in.row(0))) ||
         (r.br().x == frame.width && cv::countNonZero(in.col(in.cols - 1))) ||
         (r.br().y == frame.height && cv::countNonZero(in.row(in.rows - 1)));
}

double threshold_of(const Contrast& con, const IsolationOptions& opt) {
  return std::max(opt.min_contrast, opt.noise_k * con.noise_sigma);
}

double low_of(const IsolationOptions& opt, double threshold) {
  return std::max(opt.min_contrast / 2, opt.hysteresis * threshold);
}

}  // namespace

void isolation_levels(const Contrast& con, const IsolationOptions& opt, int& low, int& high) {
  const double t = threshold_of(con, opt);
  // 8-bit contrast above t: above floor(t).
  low = int(std::floor(low_of(opt, t)));
  high = int(std::floor(t));
}

namespace {

// A region kept for the per-object pass: its label, its box, and whether the box reaches the frame's edge.
struct Candidate {
  int label;
  cv::Rect box;
  bool edge;
};

// Labels the regions of each polarity (both in auto mode) into out.labels, apart so that a dark and a light object
// side by side stay two regions; their labels share one image, with one entry of out.sign / out.obstacle each.
// Hysteresis: a region is grown down to the low threshold from pixels above the threshold, so an object whose
// contrast dips on its relief or a dull side (a worn coin on a textured cloth) stays one region, while table
// texture that never reaches the threshold stays out. Cleaning: a 3x3 opening (isolated noise pixels and
// hairlines). A polarity with nothing above the threshold adds no regions (the usual case for one of the two).
// Returns the count of pixels above the threshold.
long long label_regions(const Contrast& con, const IsolationOptions& opt, const Labelling* dark, Isolation& out,
                        std::vector<Component>& regions) {
  const cv::Mat& d = con.gray;
  const std::vector<int> signs = con.sign == 0 ? std::vector<int>{-1, +1} : std::vector<int>{con.sign};
  out.labels = cv::Mat();  // the dark polarity's, or a zeroed frame for the first pass below
  out.obstacle.assign(1, 0);
  out.sign.assign(1, 0);
  regions.assign(1, Component{});
  std::vector<Component> comps;
  long long fg_pixels = 0;
  int low_i = 0, high_i = 0;
  isolation_levels(con, opt, low_i, high_i);
  for (int sg : signs) {
    if (dark && sg < 0 && sg == signs.front() && dark->low == low_i && dark->high == high_i &&
        dark->first_label == 1 && !dark->clear && dark->labels && dark->labels->size() == d.size() &&
        dark->labels->type() == CV_32S) {
      out.labels = *dark->labels;
      comps = *dark->comps;
      fg_pixels += dark->above_high;
    } else {
      if (out.labels.empty()) out.labels = label_frame(d.size());
      fg_pixels += label_components(con.gray, con.background, sg, low_i, high_i, int(regions.size()), out.labels, comps);
    }
    for (const Component& c : comps) label_frame_written(out.labels, c.box);
    for (const Component& c : comps) {
      regions.push_back(c);
      out.sign.push_back(int8_t(sg));
      out.obstacle.push_back(0);
    }
  }
  return fg_pixels;
}

// The regions that reach the threshold and the speck size, in label order; the smaller ones are counted as
// specks. A region cut by the frame's edge is no object; but a crowd of touching objects (water_coins.jpg's 24
// coins, one region reaching the left and bottom edges) is split first, and only its bodies cut by the edge go.
std::vector<Candidate> candidates(const std::vector<Component>& regions, const IsolationOptions& opt, cv::Size frame,
                                  Isolation& out) {
  std::vector<Candidate> keep;
  for (int i = 1; i < int(regions.size()); ++i) {
    const Component& r = regions[size_t(i)];
    if (!r.strong) continue;  // never reaches the threshold: not an object
    if (r.area < opt.min_area_px) {
      ++out.specks;
      continue;
    }
    out.obstacle[size_t(i)] = 1;
    const cv::Rect& b = r.box;
    const bool edge = b.x == 0 || b.y == 0 || b.br().x == frame.width || b.br().y == frame.height;
    if (edge && !opt.split_touching) {
      ++out.border;
      continue;
    }
    keep.push_back({i, b, edge});
  }
  return keep;
}

// The mask without its outlines under the speck size: cut by the edge, a region's specks (a fleck on
// water_coins.jpg's scan beside its crowd of coins) are left out of the split, which takes one outline only.
cv::Mat without_specks(const cv::Mat& inside, int min_area_px) {
  std::vector<std::vector<cv::Point>> outlines;
  cv::findContours(inside, outlines, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  cv::Mat whole = inside.clone();
  for (size_t i = 0; i < outlines.size(); ++i)
    if (cv::contourArea(outlines[i]) < min_area_px) cv::drawContours(whole, outlines, int(i), cv::Scalar(0), cv::FILLED);
  return whole;
}

// The per-object pass over each kept region: its soft layer, then one object, touching bodies cut apart, or the
// pieces that come apart at the half level, each appended to out.layers (new pieces get labels of their own).
class RegionPass {
 public:
  RegionPass(const Contrast& con, const IsolationOptions& opt, Isolation& out)
      : con_(con), opt_(opt), out_(out), frame_(0, 0, con.gray.cols, con.gray.rows),
        low_(low_of(opt, out.threshold)), shelf_(opt.soft_shade && con.modelled) {}

  void run(const Candidate& k) {
    Layer layer;
    const int sg = out_.sign[size_t(k.label)];
    cv::Rect kbox = k.box;
    const int table = local_table(con_, out_.labels, k.label, sg, low_, kbox);
    make_layer(con_, out_.labels, k.label, sg, grow(kbox), out_.threshold, layer, shelf_, table);
    const bool edge = k.edge && inside_at_edge(layer, frame_.size());
    int big = 0;
    for (const auto& p : layer.pieces) big += p.first >= opt_.min_area_px;
    if (edge && big > 1) {  // apart at the half level: cut by the edge as a whole
      ++out_.border;
      return;
    }
    if (big > 1) return half_level_pieces(layer, k.label, sg, table);
    if (cv::countNonZero(layer.inside) < opt_.min_area_px) {
      ++out_.specks;
      return;
    }
    layer.pieces.clear();
    cv::Mat parts;
    const int bodies = touching_bodies(layer, edge, sg, table, parts);
    // Cut by the edge, a crowd (three bodies or more) is kept apart; one body and its neighbour may be an object
    // and its own shadow running off the frame (the shadow-strong scenes: kept, both came out misshapen), dropped
    // whole.
    if (bodies <= 1 || (edge && bodies < 3)) {
      if (edge) ++out_.border;
      else out_.layers.push_back(std::move(layer));
      return;
    }
    cut_bodies(layer, parts, bodies, k.label, sg, table, edge);
  }

 private:
  cv::Rect grow(cv::Rect box) const {
    return cv::Rect(box.x - opt_.margin_px, box.y - opt_.margin_px, box.width + 2 * opt_.margin_px,
                    box.height + 2 * opt_.margin_px) & frame_;
  }

  int new_label(int sg) {
    const int id = int(out_.obstacle.size());
    out_.obstacle.push_back(1);
    out_.sign.push_back(int8_t(sg));
    return id;
  }

  // The layer of a piece given a label of its own, grown around its box.
  Layer layer_of(int id, int sg, cv::Rect box, int table) const {
    Layer piece;
    make_layer(con_, out_.labels, id, sg, grow(box), out_.threshold, piece, shelf_, table);
    piece.pieces.clear();
    return piece;
  }

  // The count of touching bodies in the region (`parts`: their labels); bodies of different contrast are cut
  // where the contrast changes (a dark sweet before a red one).
  int touching_bodies(const Layer& layer, bool edge, int sg, int table, cv::Mat& parts) const {
    if (!opt_.split_touching) return 1;
    SplitOptions so = opt_.split;
    so.min_area_px = opt_.min_area_px;
    const int bodies = split_touching(edge ? without_specks(layer.inside, opt_.min_area_px) : layer.inside, so, parts);
    if (bodies > 1) {
      cv::Mat contrast(layer.roi.size(), CV_8U);
      const cv::Mat g = con_.gray(layer.roi), bg = con_.background(layer.roi);
      for (int y = 0; y < contrast.rows; ++y)
        contrast_row(g.ptr<uchar>(y), bg.ptr<uchar>(y), sg, table, contrast.cols, contrast.ptr<uchar>(y));
      cut_between_levels(contrast, con_.noise_sigma, bodies, parts);
    }
    return bodies;
  }

  // Touching objects: each body gets a label of its own; the soft edge band around the bodies (the component's
  // pixels outside the half level) goes to the nearest body.
  void cut_bodies(const Layer& layer, const cv::Mat& parts, int bodies, int label, int sg, int table, bool edge) {
    cv::Mat lab = out_.labels(layer.roi), own = lab == label, p16;
    parts.convertTo(p16, CV_16U);
    for (int i = 0; i < opt_.margin_px + 2; ++i) {
      cv::Mat grown;
      cv::dilate(p16, grown, cv::Mat());
      grown.copyTo(p16, (p16 == 0) & own);
    }
    for (int b = 1; b <= bodies; ++b) {
      const int id = new_label(sg);
      cv::Mat body = (p16 == b) & own;
      lab.setTo(id, body);
      Layer piece = layer_of(id, sg, cv::boundingRect(body) + layer.roi.tl(), table);
      piece.touching = true;
      if (edge && inside_at_edge(piece, frame_.size())) ++out_.border;
      else if (cv::countNonZero(piece.inside) >= opt_.min_area_px) out_.layers.push_back(std::move(piece));
    }
  }

  // Near objects joined by their blurred edges at the low threshold come apart at the half level: each piece big
  // enough becomes an object of its own. A piece far fainter and smaller than another piece of its region is that
  // object's soft shadow (the shade between two sweets joins them at the low threshold), not an object nor an
  // obstacle.
  void half_level_pieces(const Layer& layer, int label, int sg, int table) {
    std::vector<Layer> pieces;
    for (const auto& p : layer.pieces) {
      if (p.first < opt_.min_area_px) continue;
      const int id = new_label(sg);
      cv::Mat mask(layer.roi.size(), CV_8U, cv::Scalar(0));
      cv::drawContours(mask, std::vector<std::vector<cv::Point>>{p.second}, 0, cv::Scalar(255), cv::FILLED);
      cv::Mat lab = out_.labels(layer.roi);
      lab.setTo(id, mask & (lab == label));
      Layer piece = layer_of(id, sg, cv::boundingRect(p.second) + layer.roi.tl(), table);
      if (cv::countNonZero(piece.inside) >= opt_.min_area_px) pieces.push_back(std::move(piece));
    }
    std::vector<char> shade(pieces.size(), 0);
    for (size_t i = 0; i < pieces.size(); ++i)
      for (const Layer& other : pieces)
        shade[i] = shade[i] || (other.level >= opt_.fringe_ratio * pieces[i].level &&
                                cv::countNonZero(pieces[i].inside) <= 0.25 * cv::countNonZero(other.inside));
    for (size_t i = 0; i < pieces.size(); ++i) {
      if (shade[i]) {
        ++out_.fringes;
        out_.obstacle[size_t(pieces[i].label)] = 0;
      } else {
        out_.layers.push_back(std::move(pieces[i]));
      }
    }
  }

  const Contrast& con_;
  const IsolationOptions& opt_;
  Isolation& out_;
  const cv::Rect frame_;
  const double low_;
  const bool shelf_;  // a captured background has its own shade model
};

}  // namespace

bool isolate(const Contrast& con, const IsolationOptions& opt, Isolation& out, std::string& error,
             const Labelling* dark) {
  out.threshold = threshold_of(con, opt);
  std::vector<Component> regions;
  const double fg = double(label_regions(con, opt, dark, out, regions)) / double(con.gray.total());
  if (fg > opt.max_foreground) {
    error = "frame is " + std::to_string(int(std::lround(fg * 100))) +
            "% foreground: wrong background image or polarity, or no table in view";
    return false;
  }
  RegionPass pass(con, opt, out);
  for (const Candidate& k : candidates(regions, opt, con.gray.size(), out)) pass.run(k);
  drop_fringes(con, opt, out);
  // Detection order: by rows of the top edge, then left to right (split pieces included).
  std::stable_sort(out.layers.begin(), out.layers.end(), [](const Layer& a, const Layer& b) {
    return a.roi.y != b.roi.y ? a.roi.y < b.roi.y : a.roi.x < b.roi.x;
  });
  return true;
}

}  // namespace rbx1::vision
