// shadow.cpp - cast shadows against a coloured background: the per-channel ratio test (frame / background).
#include "shadow.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include <opencv2/imgproc.hpp>

#include "avx2_clones.hpp"
#include "components.hpp"
#include "pixels.hpp"

namespace rbx1::vision {
namespace {

// Median chroma (max - min channel) of the background, smoothed so sensor noise adds none.
double median_chroma(const cv::Mat& background) {
  cv::Mat small;
  cv::resize(background, small, cv::Size(), 0.25, 0.25, cv::INTER_AREA);
  int hist[256] = {0};
  for (int y = 0; y < small.rows; ++y) {
    const cv::Vec3b* r = small.ptr<cv::Vec3b>(y);
    for (int x = 0; x < small.cols; ++x) {
      const int hi = std::max({r[x][0], r[x][1], r[x][2]}), lo = std::min({r[x][0], r[x][1], r[x][2]});
      hist[hi - lo]++;
    }
  }
  const int n = int(small.total());
  for (int i = 0, acc = 0; i < 256; ++i)
    if ((acc += hist[i]) * 2 >= n) return i;
  return 0;
}

}  // namespace

bool coloured_background(const cv::Mat& background_bgr, const ShadowOptions& opt) {
  return background_bgr.type() == CV_8UC3 && median_chroma(background_bgr) >= opt.min_chroma;
}

// (The byte loops take 32 pixels at a time where the CPU has AVX2, as in components.cpp; no fused multiply-adds.)
RBX1_AVX2_CLONES
int grey_shade_mask(const cv::Mat& gray, const cv::Mat& background, const GreyShadeOptions& opt, cv::Mat& mask,
                    cv::Mat& shaded, Labelling* also) {
  mask.release();
  shaded.release();
  if (gray.type() != CV_8U || background.type() != CV_8U || gray.size() != background.size()) return 0;
  // Candidates: darker than the table by at least min_depth levels, opened 3x3, 8-connected: the isolation's
  // streamed pass (components.cpp), its labels in a buffer kept zero between frames (each region's box is
  // cleared after use).
  const int depth = int(std::ceil(opt.min_depth));
  thread_local cv::Mat lab;
  thread_local std::vector<Component> regions;
  if (lab.size() != gray.size()) lab = cv::Mat::zeros(gray.size(), CV_32S);
  if (also) {
    Labelling both[2] = {{depth - 1, depth - 1, 1, &lab, &regions, false}, *also};
    label_components(gray, background, -1, both, 2);
    *also = both[1];
  } else {
    label_components(gray, background, -1, depth - 1, depth - 1, 1, lab, regions);
  }
  struct Clear {  // (on every way out)
    ~Clear() {
      for (const Component& c : regions) lab(c.box).setTo(0);
    }
  } clear;
  // Each region split in two by its ratio (Otsu): the lighter part is shade when it is no larger than the
  // darker part, lies against it, and borders the lit table along part of its outline. All work is on the
  // region's box grown by 3 px.
  const cv::Rect frame(0, 0, gray.cols, gray.rows);
  int total = 0;
  // The ratio gray / background on 0-255, min(255, 255 g / max(b, 1)), tabled for every (background, grey) pair
  // (64 KiB), so the per-pixel loops below are lookups.
  static const std::vector<uchar> ratio_table = [] {
    std::vector<uchar> t(256 * 256);
    for (int b = 0; b < 256; ++b)
      for (int g = 0; g < 256; ++g) t[size_t(b * 256 + g)] = uchar(std::min(255, 255 * g / std::max(b, 1)));
    return t;
  }();
  for (size_t k = 0; k < regions.size(); ++k) {
    const int i = int(k) + 1;
    if (regions[k].area < 2 * opt.min_area_px) continue;
    const cv::Rect box = regions[k].box;
    const cv::Rect r = cv::Rect(box.x - 3, box.y - 3, box.width + 6, box.height + 6) & frame;
    // In one pass over the box: the region's pixels (`own`), the ratio on them (0 elsewhere) and its histogram
    // over them (by column mod 4, so that equal neighbours do not wait on each other's count; bin 0 from the
    // region's area).
    cv::Mat own(r.size(), CV_8U), q(r.size(), CV_8U);
    int hist4[4][256] = {}, hist[256];
    const uchar* table = ratio_table.data();  // (a local: byte stores may alias the vector's own pointer)
    for (int y = 0; y < r.height; ++y) {
      const int* lr = lab.ptr<int>(r.y + y) + r.x;
      const uchar* g = gray.ptr<uchar>(r.y + y) + r.x;
      const uchar* b = background.ptr<uchar>(r.y + y) + r.x;
      uchar* o = own.ptr<uchar>(y);
      uchar* qq = q.ptr<uchar>(y);
      const int w = r.width;
      for (int x = 0; x < w; ++x) o[x] = uchar(-int(lr[x] == i));
      // 8 pixels at a time: none of the region's (the box's corners, a neighbour) counts only in bin 0.
      int x = 0;
      for (; x + 8 <= w; x += 8) {
        uint64_t any;
        std::memcpy(&any, o + x, 8);
        if (!any) {
          std::memset(qq + x, 0, 8);
          continue;
        }
        for (int k = 0; k < 8; ++k) hist4[k & 3][qq[x + k] = table[size_t(b[x + k]) * 256 + g[x + k]] & o[x + k]]++;
      }
      for (; x < w; ++x) hist4[x & 3][qq[x] = table[size_t(b[x]) * 256 + g[x]] & o[x]]++;
    }
    hist[0] = regions[k].area;
    for (int v = 1; v < 256; ++v) hist[0] -= hist[v] = hist4[0][v] + hist4[1][v] + hist4[2][v] + hist4[3][v];
    // Otsu's threshold over the region's ratios.
    double sum = 0, cnt = 0;
    for (int v = 0; v < 256; ++v) sum += double(v) * hist[v], cnt += hist[v];
    double best = -1, s0 = 0, c0 = 0;
    int t = 0;
    for (int v = 0; v < 255; ++v) {
      s0 += double(v) * hist[v], c0 += hist[v];
      if (c0 == 0 || c0 == cnt) continue;
      const double m0 = s0 / c0, m1 = (sum - s0) / (cnt - c0), between = c0 * (cnt - c0) * (m1 - m0) * (m1 - m0);
      if (between > best) best = between, t = v + 1;
    }
    // Then halfway between the two parts' medians (k-medians): a large dark object would otherwise pull
    // the threshold into the shade's plateau.
    auto median_in = [&](int from, int to) {
      int c = 0, acc = 0;
      for (int v = from; v < to; ++v) c += hist[v];
      for (int v = from; v < to; ++v)
        if ((acc += hist[v]) * 2 >= c) return v;
      return from;
    };
    for (int it = 0; it < 4 && t > 0 && t < 256; ++it) t = (median_in(0, t) + median_in(t, 256) + 1) / 2;
    // The darker part is its plateau (median and spread); all above it goes to the lighter side, so that the
    // threshold never cuts through the shade's plateau (the darker part's edge is set apart below).
    const int med_a = median_in(0, t);
    {
      int dev[256] = {0}, c = 0, acc = 0, mad = 0;
      for (int v = 0; v < t; ++v) dev[std::abs(v - med_a)] += hist[v], c += hist[v];
      for (int v = 0; v < 256; ++v)
        if ((acc += dev[v]) * 2 >= c) {
          mad = v;
          break;
        }
      t = std::min(t, med_a + std::max(13, 4 * mad));
    }
    double sa = 0, ca = 0;
    for (int v = 0; v < t; ++v) sa += double(v) * hist[v], ca += hist[v];
    const double ma = sa / std::max(ca, 1.0), mb = (sum - sa) / std::max(cnt - ca, 1.0);
    if (ca == 0 || mb - ma < 255 * opt.caster_margin || mb < 255 * opt.min_ratio) continue;
    // The darker part's blurred rim (up to 4 px wide) lies in the lighter range too: an opening leaves only
    // pieces of real extent (each then regains its own corners). Most regions are an object with its rim
    // alone: nothing survives the opening.
    cv::Mat part_a(r.size(), CV_8U), part_b = own & (q >= t);
    if (!opening5_any(part_b)) continue;
    for (int y = 0; y < r.height; ++y) {
      const uchar* o = own.ptr<uchar>(y);
      const uchar* qq = q.ptr<uchar>(y);
      uchar* pa = part_a.ptr<uchar>(y);
      for (int x = 0; x < r.width; ++x) pa[x] = uchar(o[x] && qq[x] < t ? 255 : 0);
    }
    cv::Mat near_a, plab, pstats, pcents, seeds;
    cv::morphologyEx(part_b, seeds, cv::MORPH_OPEN, cv::Mat::ones(5, 5, CV_8U));
    cv::dilate(part_a, near_a, cv::Mat::ones(5, 5, CV_8U));
    const int np = cv::connectedComponentsWithStats(seeds, plab, pstats, pcents, 8, CV_32S);
    bool found = false;
    for (int j = 1; j < np; ++j) {
      const int area = pstats.at<int>(j, cv::CC_STAT_AREA);
      if (area < opt.min_area_px || area > ca) continue;
      long soft = 0, edge = 0, against = 0;
      for (int y = 0; y < r.height; ++y) {
        const int* pl = plab.ptr<int>(y);
        const uchar* na = near_a.ptr<uchar>(y);
        for (int x = 0; x < r.width; ++x) {
          if (pl[x] != j) continue;
          against += na[x] != 0;
          const int nx[4] = {x - 1, x + 1, x, x}, ny[4] = {y, y, y - 1, y + 1};
          for (int k = 0; k < 4; ++k) {
            if (nx[k] < 0 || ny[k] < 0 || nx[k] >= r.width || ny[k] >= r.height) continue;
            if (plab.at<int>(ny[k], nx[k]) == j) continue;
            ++edge;
            soft += background.at<uchar>(r.y + ny[k], r.x + nx[k]) - gray.at<uchar>(r.y + ny[k], r.x + nx[k]) < depth;
          }
        }
      }
      if (against < 3 || soft < opt.min_soft * double(edge)) continue;
      // The piece holds the darker part's blurred edge too: the shade is what reaches its 20th percentile
      // (less the noise); the edge below is left to the coverage correction.
      int ph[256] = {0}, pn = 0, kp = 0;
      cv::Mat piece = plab == j, grown;
      for (int it = 0; it < 2; ++it) {
        cv::dilate(piece, grown, cv::Mat::ones(3, 3, CV_8U));
        piece = grown & part_b;
      }
      for (int y = 0; y < r.height; ++y) {
        const uchar* pm = piece.ptr<uchar>(y);
        const uchar* qq = q.ptr<uchar>(y);
        for (int x = 0; x < r.width; ++x)
          if (pm[x]) ph[qq[x]]++, ++pn;
      }
      for (int v = 0, acc = 0; v < 256; ++v)
        if ((acc += ph[v]) * 5 >= pn) {
          kp = v;
          break;
        }
      // A shade shallower than 40 % of the darker part's depth is below its half level already (the
      // isolation's soft layer leaves it out): left alone.
      if (255 - kp < 0.4 * (255 - med_a)) continue;
      // A penumbra is soft: its 25-75 % band between the piece's level and the lit table is wider than an
      // object's blurred edge (on average over the piece's table side, in px).
      const int band_lo = kp + (255 - kp) / 4, band_hi = kp + 3 * (255 - kp) / 4;
      long band = 0;
      for (int v = band_lo; v <= band_hi; ++v) band += ph[v];
      if (double(band) < opt.min_penumbra_px * double(soft)) continue;
      piece &= q >= kp - 6;
      if (mask.empty()) mask = cv::Mat::zeros(gray.size(), CV_8U);
      mask(r).setTo(255, piece);
      total += cv::countNonZero(piece);
      found = true;
    }
    if (!found) continue;
    // The background in the shade: background * (gray / background) on the shade; beside it (the darker part's
    // edge over shaded table, within 2 px) the background that gives such a pixel its true coverage of the
    // darker part (the part's median ratio over the shade's ratio nearby), so the outline neither bulges into
    // the shade nor bites into itself.
    if (shaded.empty()) shaded = background.clone();
    int acc = 0, med = 0;
    for (int v = 0; v < t; ++v)
      if ((acc += hist[v]) * 2 >= int(ca)) {
        med = v;
        break;
      }
    const float o = float(med) / 255.f;
    cv::Mat sh = mask(r), shade_ratio(r.size(), CV_32F, cv::Scalar(0)), weight, spread;
    for (int y = 0; y < r.height; ++y) {
      const uchar* m = sh.ptr<uchar>(y);
      const uchar* g = gray.ptr<uchar>(r.y + y) + r.x;
      const uchar* b = background.ptr<uchar>(r.y + y) + r.x;
      float* rr = shade_ratio.ptr<float>(y);
      for (int x = 0; x < r.width; ++x)
        if (m[x]) rr[x] = float(ratio_table[size_t(b[x]) * 256 + g[x]]) / 255.f;  // (earlier regions' shade too)
    }
    sh.convertTo(weight, CV_32F, 1.0 / 255);
    cv::boxFilter(shade_ratio, spread, CV_32F, cv::Size(5, 5), cv::Point(-1, -1), false);
    cv::boxFilter(weight, weight, CV_32F, cv::Size(5, 5), cv::Point(-1, -1), false);
    for (int y = 0; y < r.height; ++y) {
      const uchar* m = sh.ptr<uchar>(y);
      const uchar* ow = own.ptr<uchar>(y);
      const uchar* g = gray.ptr<uchar>(r.y + y) + r.x;
      const uchar* b = background.ptr<uchar>(r.y + y) + r.x;
      const float* sp = spread.ptr<float>(y);
      const float* w = weight.ptr<float>(y);
      uchar* s = shaded.ptr<uchar>(r.y + y) + r.x;
      for (int x = 0; x < r.width; ++x) {
        const float v = float(g[x]) / float(std::max<int>(b[x], 1));
        float f;
        if (m[x]) {
          f = v;
        } else if (ow[x] && w[x] > 0) {
          const float kk = sp[x] / w[x];
          if (v >= kk || kk <= o) f = std::min(1.f, v);
          else f = std::min(1.f, v + std::clamp((kk - v) / (kk - o), 0.f, 1.f) * (1.f - o));
        } else {
          continue;
        }
        s[x] = cv::saturate_cast<uchar>(float(b[x]) * f);
      }
    }
  }
  return total;
}

int shadow_mask(const cv::Mat& frame, const cv::Mat& background, const LightFit& light, const ShadowOptions& opt,
                cv::Mat& mask) {
  mask = cv::Mat::zeros(frame.size(), CV_8U);
  if (frame.type() != CV_8UC3 || background.type() != CV_8UC3 || frame.size() != background.size()) return 0;
  if (median_chroma(background) < opt.min_chroma) return 0;
  // The background in the scene's light, per channel, and the noise's share of each ratio.
  float lut[256], tol[256];
  for (int v = 0; v < 256; ++v) {
    lut[v] = float(std::max(1.0, light.gain * v + light.offset));
    tol[v] = float(opt.max_spread + 8.0 / lut[v]);
  }
  for (int y = 0; y < frame.rows; ++y) {
    const cv::Vec3b* f = frame.ptr<cv::Vec3b>(y);
    const cv::Vec3b* b = background.ptr<cv::Vec3b>(y);
    uchar* m = mask.ptr<uchar>(y);
    for (int x = 0; x < frame.cols; ++x) {
      const float b0 = lut[b[x][0]], b1 = lut[b[x][1]], b2 = lut[b[x][2]];
      const float r = float(f[x][0] + f[x][1] + f[x][2]) / (b0 + b1 + b2);
      if (r < opt.min_ratio || r > opt.max_ratio) continue;
      const bool alike = std::abs(f[x][0] / b0 - r) <= tol[b[x][0]] && std::abs(f[x][1] / b1 - r) <= tol[b[x][1]] &&
                         std::abs(f[x][2] / b2 - r) <= tol[b[x][2]];
      m[x] = alike ? 255 : 0;
    }
  }
  cv::morphologyEx(mask, mask, cv::MORPH_OPEN, cv::Mat::ones(3, 3, CV_8U));
  return cv::countNonZero(mask);
}

}  // namespace rbx1::vision
