// pixels.cpp - fused pixel loops over the objects' ROIs, bit-equal to the OpenCV calls they replace.
#include "pixels.hpp"

#include "avx2_clones.hpp"

#include <algorithm>
#include <cstring>
#include <vector>

namespace rbx1::vision {

namespace {

// o[i] = max(a[i], b[i]) for i < n (b may lie inside a's buffer: both are only read).
inline void max_of(const uchar* __restrict a, const uchar* __restrict b, uchar* __restrict o, size_t n) {
  for (size_t i = 0; i < n; ++i) o[i] = std::max(a[i], b[i]);
}

// The maximum over a window of n elements step apart: out[i] = max of src[i + k step], k < n, for i < count
// (src holds count + (n - 1) step elements). By doubling: maxima over 2, 4, ... elements (ping-ponged
// between a and b, each holding the source's size), then two overlapping windows of the largest power of two
// (max is idempotent, so the same values as the plain n - 1 maxima, in about log2(n) + 1 passes).
inline void window_max(const uchar* src, size_t count, size_t step, int n, uchar* a, uchar* b, uchar* out) {
  const size_t total = count + size_t(n - 1) * step;
  const uchar* m = src;
  size_t len = 1;
  for (; 2 * len <= size_t(n); len *= 2) {
    const size_t valid = total - (2 * len - 1) * step;  // windows of 2 len elements that fit
    max_of(m, m + len * step, a, valid);
    m = a;
    std::swap(a, b);
  }
  if (len == size_t(n)) std::memcpy(out, m, count);
  else max_of(m, m + (size_t(n) - len) * step, out, count);
}

}  // namespace

// The byte and float loops take 32 bytes at a time where the CPU has AVX2 (a clone chosen when the program
// loads; without fused multiply-adds, so the results are the same either way).
RBX1_AVX2_CLONES
void dilate_square(const cv::Mat& src, cv::Mat& dst, int r) {
  CV_Assert(src.type() == CV_8U && r >= 0);
  const int W = src.cols, H = src.rows;
  const int n = 2 * r + 1;
  // Rows first (each padded with r zeros on both sides), then columns over rows padded with r zero rows above
  // and below (cv::dilate's border leaves the maximum unchanged: the same as zeros), into a buffer: dst may be
  // src.
  const size_t PW = size_t(W) + 2 * size_t(r), WH = size_t(W) * size_t(H) + 2 * size_t(r) * size_t(W);
  thread_local std::vector<uchar> pad, ta, tb, rows;
  pad.assign(PW, 0);
  ta.resize(std::max(PW, WH));
  tb.resize(std::max(PW, WH));
  rows.resize(WH);
  const size_t band = size_t(r) * size_t(W);  // the r zero rows above and below; the rows between are written
  std::memset(rows.data(), 0, band);
  std::memset(rows.data() + WH - band, 0, band);
  uchar* body = rows.data() + band;  // row 0 of the frame's rows in the padded column buffer
  for (int y = 0; y < H; ++y) {
    std::memcpy(pad.data() + r, src.ptr<uchar>(y), size_t(W));
    window_max(pad.data(), size_t(W), 1, n, ta.data(), tb.data(), body + size_t(y) * size_t(W));
  }
  dst.create(H, W, CV_8U);
  if (dst.isContinuous()) {
    window_max(rows.data(), size_t(W) * size_t(H), size_t(W), n, ta.data(), tb.data(), dst.ptr<uchar>());
  } else {
    thread_local std::vector<uchar> out;
    out.resize(size_t(W) * size_t(H));
    window_max(rows.data(), size_t(W) * size_t(H), size_t(W), n, ta.data(), tb.data(), out.data());
    for (int y = 0; y < H; ++y) std::memcpy(dst.ptr<uchar>(y), out.data() + size_t(y) * size_t(W), size_t(W));
  }
}

namespace {

// OpenCV's default border (BORDER_REFLECT_101): -1 -> 1, n -> n - 2.
int reflect101(int i, int n) {
  if (n == 1) return 0;
  return i < 0 ? -i : i >= n ? 2 * n - 2 - i : i;
}

}  // namespace

RBX1_AVX2_CLONES
int sobel_gradient(const cv::Mat& s, cv::Mat& gx, cv::Mat& gy, float t2) {
  CV_Assert(s.type() == CV_32F);
  const int W = s.cols, H = s.rows;
  gx.create(H, W, CV_32F);
  gy.create(H, W, CV_32F);
  if (W == 0 || H == 0) return 0;
  // cv::Sobel is separable: dx = 1 filters rows with [-1 0 1] and columns with [1 2 1]/8 (the scale goes to
  // the smoothing kernel), dy = 1 rows with [1 2 1]/8 and columns with [-1 0 1]; each pass rounds to float,
  // the symmetric taps summed first: (a + c) * 1/8 + b * 1/4.
  thread_local std::vector<float> buf;
  buf.resize(2 * size_t(W) * size_t(H));
  float* D = buf.data();                         // rows of gx's first pass
  float* M = buf.data() + size_t(W) * size_t(H);  // rows of gy's first pass
  const int xl = reflect101(-1, W), xr = reflect101(W, W);
  for (int y = 0; y < H; ++y) {
    const float* p = s.ptr<float>(y);
    float* d = D + size_t(y) * size_t(W);
    float* m = M + size_t(y) * size_t(W);
    d[0] = p[reflect101(1, W)] - p[xl];
    m[0] = (p[xl] + p[reflect101(1, W)]) * 0.125f + p[0] * 0.25f;
    for (int x = 1; x < W - 1; ++x) {
      d[x] = p[x + 1] - p[x - 1];
      m[x] = (p[x - 1] + p[x + 1]) * 0.125f + p[x] * 0.25f;
    }
    if (W > 1) {
      d[W - 1] = p[xr] - p[W - 2];
      m[W - 1] = (p[W - 2] + p[xr]) * 0.125f + p[W - 1] * 0.25f;
    }
  }
  int count = 0;
  for (int y = 0; y < H; ++y) {
    const float* da = D + size_t(reflect101(y - 1, H)) * size_t(W);
    const float* db = D + size_t(y) * size_t(W);
    const float* dc = D + size_t(reflect101(y + 1, H)) * size_t(W);
    const float* ma = M + size_t(reflect101(y - 1, H)) * size_t(W);
    const float* mc = M + size_t(reflect101(y + 1, H)) * size_t(W);
    float* ox = gx.ptr<float>(y);
    float* oy = gy.ptr<float>(y);
    for (int x = 0; x < W; ++x) ox[x] = (da[x] + dc[x]) * 0.125f + db[x] * 0.25f;
    for (int x = 0; x < W; ++x) oy[x] = mc[x] - ma[x];
    int row = 0;
    for (int x = 0; x < W; ++x) row += ox[x] * ox[x] + oy[x] * oy[x] > t2 ? 1 : 0;
    count += row;
  }
  return count;
}

cv::Moments moments_second_order(const cv::Mat& s) {
  CV_Assert(s.type() == CV_32F);
  // cv::moments' own order of operations: 32x32 tiles; in each, per row the sums of p, x p and x^2 p (double,
  // left to right), folded row by row into the tile's moments, which are shifted to the tile's origin and added
  // to the totals. Four rows run side by side here (independent sums, so the same values).
  constexpr int kTile = 32;
  const int W = s.cols, H = s.rows;
  double m00 = 0, m10 = 0, m01 = 0, m20 = 0, m11 = 0, m02 = 0;
  for (int ty = 0; ty < H; ty += kTile) {
    const int th = std::min(kTile, H - ty);
    for (int tx = 0; tx < W; tx += kTile) {
      const int tw = std::min(kTile, W - tx);
      double mom[6] = {0, 0, 0, 0, 0, 0};
      for (int y = 0; y < th; y += 4) {
        const int n = std::min(4, th - y);
        const float* row[4];
        for (int r = 0; r < 4; ++r) row[r] = s.ptr<float>(ty + y + std::min(r, n - 1)) + tx;
        double x0[4] = {0, 0, 0, 0}, x1[4] = {0, 0, 0, 0}, x2[4] = {0, 0, 0, 0};
        for (int x = 0; x < tw; ++x) {
          const double xd = x;
          for (int r = 0; r < 4; ++r) {
            const double p = row[r][x], xp = xd * p;
            x0[r] += p;
            x1[r] += xp;
            x2[r] += xp * xd;
          }
        }
        for (int r = 0; r < n; ++r) {
          const int yi = y + r;
          const double yd = yi, py = yd * x0[r], sy = double(yi * yi);
          mom[5] += x0[r] * sy;
          mom[4] += x1[r] * yd;
          mom[3] += x2[r];
          mom[2] += py;
          mom[1] += x1[r];
          mom[0] += x0[r];
        }
      }
      const double x = tx, y = ty, xm = x * mom[0], ym = y * mom[0];
      m00 += mom[0];
      m10 += mom[1] + xm;
      m01 += mom[2] + ym;
      m20 += mom[3] + x * (mom[1] * 2 + xm);
      m11 += mom[4] + x * (mom[2] + ym) + y * mom[1];
      m02 += mom[5] + y * (mom[2] * 2 + ym);
    }
  }
  cv::Moments m;
  m.m00 = m00, m.m10 = m10, m.m01 = m01, m.m20 = m20, m.m11 = m11, m.m02 = m02;
  double cx = 0, cy = 0;
  if (std::abs(m00) > DBL_EPSILON) {
    const double inv = 1. / m00;
    cx = m10 * inv;
    cy = m01 * inv;
  }
  m.mu20 = m20 - m10 * cx;
  m.mu11 = m11 - m10 * cy;
  m.mu02 = m02 - m01 * cy;
  return m;
}

RBX1_AVX2_CLONES
bool opening5_any(const cv::Mat& m) {
  CV_Assert(m.type() == CV_8U);
  const int W = m.cols, H = m.rows;
  // The opening has a pixel where its erosion has one: the minimum over 5 pixels of each row (padded with 2
  // set pixels on both sides), then over 5 such rows (rows outside the image set), is not 0 somewhere.
  thread_local std::vector<uchar> pad, rows;
  pad.assign(size_t(W) + 4, 255);
  rows.assign(5 * size_t(W), 255);  // the last 5 rows' minima, row y at y % 5
  for (int y = 0; y < H + 2; ++y) {
    uchar* h = rows.data() + size_t(y % 5) * size_t(W);
    if (y < H) {
      std::memcpy(pad.data() + 2, m.ptr<uchar>(y), size_t(W));
      const uchar* p = pad.data();
      for (int x = 0; x < W; ++x)
        h[x] = std::min(std::min(std::min(p[x], p[x + 1]), std::min(p[x + 2], p[x + 3])), p[x + 4]);
    } else {
      std::memset(h, 255, size_t(W));
    }
    if (y < 2) continue;  // the erosion's row y - 2 needs rows y - 4 .. y
    const uchar *r0 = rows.data(), *r1 = r0 + W, *r2 = r1 + W, *r3 = r2 + W, *r4 = r3 + W;
    uchar any = 0;
    for (int x = 0; x < W; ++x)
      any |= std::min(std::min(std::min(r0[x], r1[x]), std::min(r2[x], r3[x])), r4[x]);
    if (any) return true;
  }
  return false;
}

}  // namespace rbx1::vision
