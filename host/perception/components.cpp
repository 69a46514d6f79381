// components.cpp - one polarity's cleaned binary image, streamed row by row, and its components by runs.
#include "components.hpp"

#include "avx2_clones.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>

namespace rbx1::vision {
namespace {

struct Run {
  int y, x0, x1;  // pixels x0..x1 of row y
  int parent;     // union-find over runs
  bool strong;
};

int root_of(std::vector<Run>& runs, int i) {
  while (runs[size_t(i)].parent != i) i = runs[size_t(i)].parent = runs[size_t(runs[size_t(i)].parent)].parent;
  return i;
}

// Bit k of the result is the top bit of byte k of the 8 bytes at m: 8 mask pixels (0 or 255) in 8 bits.
uint64_t pack8(const uchar* m) {
  uint64_t v;
  std::memcpy(&v, m, 8);
  return ((v & 0x8080808080808080ULL) * 0x0002040810204081ULL) >> 56;
}

// Pixel x of a row of nw * 64 mask bytes is bit x % 64 of bits[x / 64]. Only words whose bit in `where` is
// set (where = nullptr: all) can have pixels; 64 clear bytes (most of a frame is table) are skipped quickly.
void pack_bits(const uchar* m, int nw, const uint64_t* where, uint64_t* bits) {
  for (int i = 0; i < nw; ++i) {
    const uchar* c = m + 64 * i;
    uint64_t any = 0, w = 0;
    if (!where || where[i]) {
      for (int k = 0; k < 8; ++k) {
        uint64_t v;
        std::memcpy(&v, c + 8 * k, 8);
        any |= v;
      }
    }
    if (any)
      for (int k = 0; k < 8; ++k) w |= pack8(c + 8 * k) << (8 * k);
    bits[i] = w;
  }
}

// The first pixel from x on whose bit differs from `clear` (0: the next set bit, ~0: the next clear one);
// nw * 64 when there is none.
int next_bit(const uint64_t* bits, int nw, int x, uint64_t clear) {
  int i = x >> 6;
  if (i >= nw) return nw * 64;
  uint64_t w = (bits[i] ^ clear) & (~0ULL << (x & 63));
  while (!w) {
    if (++i >= nw) return nw * 64;
    w = bits[i] ^ clear;
  }
  return i * 64 + __builtin_ctzll(w);
}

// Whether any bit of pixels x0..x1 is set.
bool any_bit(const uint64_t* bits, int x0, int x1) {
  for (int i = x0 >> 6; i <= x1 >> 6; ++i) {
    uint64_t w = bits[i];
    if (i == x0 >> 6) w &= ~0ULL << (x0 & 63);
    if (i == x1 >> 6 && (x1 & 63) != 63) w &= (1ULL << ((x1 & 63) + 1)) - 1;
    if (w) return true;
  }
  return false;
}

void unite(std::vector<Run>& runs, int a, int b) {
  a = root_of(runs, a), b = root_of(runs, b);
  if (a < b) runs[size_t(b)].parent = a;
  else if (b < a) runs[size_t(a)].parent = b;
}

}  // namespace

namespace {

// One labelling's state during the sweep: its levels, its row's pixels above them (bytes, then bits) and its runs.
struct Pass {
  uchar lo = 0, hi = 0;
  std::vector<uchar> in, in_high;
  std::vector<uint64_t> lo_bits, hi_bits;
  std::vector<Run> runs;
  std::vector<int> row_start;
  long long above_high = 0;
};

// The components of one pass, numbered as OpenCV numbers them, written into its labels.
void finish(Pass& ps, int W, int H, Labelling& out) {
  std::vector<Run>& runs = ps.runs;
  const std::vector<int>& row_start = ps.row_start;
  cv::Mat& labels = *out.labels;
  std::vector<Component>& comps = *out.comps;
  out.above_high = ps.above_high;
  if (ps.above_high == 0) {  // nothing of this polarity reaches the high level: no components at all
    if (out.clear) labels.setTo(0);
    return;
  }
  // One component per root; OpenCV's numbering: by the first 2x2 block (row pair, column pair) it occupies.
  const long long bw = (W + 1) / 2;
  std::vector<int> comp_of(runs.size(), -1);
  std::vector<long long> key;
  std::vector<int> roots;
  for (size_t i = 0; i < runs.size(); ++i) {
    const int r = root_of(runs, int(i));
    const Run& u = runs[i];
    const long long k = (u.y / 2) * bw + u.x0 / 2;
    if (comp_of[size_t(r)] < 0) {
      comp_of[size_t(r)] = int(roots.size());
      roots.push_back(r);
      key.push_back(k);
    } else {
      key[size_t(comp_of[size_t(r)])] = std::min(key[size_t(comp_of[size_t(r)])], k);
    }
  }
  std::vector<int> order(roots.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = int(i);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return key[size_t(a)] < key[size_t(b)]; });
  std::vector<int> rank(roots.size());
  for (size_t i = 0; i < order.size(); ++i) rank[size_t(order[i])] = int(i);
  struct Box { int x0 = INT32_MAX, y0 = INT32_MAX, x1 = -1, y1 = -1; };
  std::vector<Box> boxes(roots.size());
  comps.assign(roots.size(), Component{});
  // Row by row (a row's runs are consecutive, left to right); with `clear` the gaps between runs are zeroed in
  // the same sweep, so the frame's labels are written once instead of zero-filled first.
  const bool clear = out.clear;
  const int first_label = out.first_label;
  for (int y = 0; y < H; ++y) {
    int* lr = labels.ptr<int>(y);
    int x = 0;
    for (int i = row_start[size_t(y)]; i < row_start[size_t(y) + 1]; ++i) {
      const Run& u = runs[size_t(i)];
      const int k = rank[size_t(comp_of[size_t(root_of(runs, i))])];
      Component& cp = comps[size_t(k)];
      Box& bx = boxes[size_t(k)];
      cp.area += u.x1 - u.x0 + 1;
      cp.strong = cp.strong || u.strong;
      bx.x0 = std::min(bx.x0, u.x0), bx.x1 = std::max(bx.x1, u.x1);
      bx.y0 = std::min(bx.y0, u.y), bx.y1 = std::max(bx.y1, u.y);
      if (clear) std::fill(lr + x, lr + u.x0, 0);
      std::fill(lr + u.x0, lr + u.x1 + 1, first_label + k);
      x = u.x1 + 1;
    }
    if (clear) std::fill(lr + x, lr + W, 0);
  }
  for (size_t k = 0; k < comps.size(); ++k)
    comps[k].box = cv::Rect(boxes[k].x0, boxes[k].y0, boxes[k].x1 - boxes[k].x0 + 1, boxes[k].y1 - boxes[k].y0 + 1);
}

}  // namespace

// The byte loops take 32 pixels at a time where the CPU has AVX2 (a clone chosen when the program loads;
// integer arithmetic only, so the results are the same either way).
RBX1_AVX2_CLONES
void label_components(const cv::Mat& gray, const cv::Mat& background, int s, Labelling* outs, int n_outs) {
  CV_Assert(gray.type() == CV_8U && background.type() == CV_8U && gray.size() == background.size());
  CV_Assert(n_outs >= 1 && n_outs <= 2);
  const int W = gray.cols, H = gray.rows;
  for (int k = 0; k < n_outs; ++k) {
    outs[k].comps->clear();
    outs[k].above_high = 0;
    if (outs[k].clear) outs[k].labels->create(gray.size(), CV_32S);
  }
  if (W == 0 || H == 0) return;
  // Rows: the contrast (3 kept for the erosion), the eroded rows (3 kept for the dilation), each padded by one
  // pixel on both sides with the value that leaves the min (255) or the max (0) unchanged: OpenCV's borders for
  // erode and dilate. Rows outside the frame are those constants too.
  const size_t P = size_t(W) + 2;
  std::vector<uchar> buf(P * 8);
  uchar* c[3] = {buf.data(), buf.data() + P, buf.data() + 2 * P};
  uchar* e[3] = {buf.data() + 3 * P, buf.data() + 4 * P, buf.data() + 5 * P};
  uchar* tmp = buf.data() + 6 * P;
  uchar* full = buf.data() + 7 * P;  // 255 everywhere
  // The opened row; per pass, the row's pixels above the low and the high level as bytes (0 or 255),
  // zero-padded to whole 64-pixel words, and as bits.
  const int nw = (W + 63) / 64;
  std::vector<uchar> zero(P, 0), opened(size_t(nw) * 64, 0);
  Pass passes[2];
  for (int k = 0; k < n_outs; ++k) {
    Pass& ps = passes[k];
    ps.lo = uchar(std::clamp(outs[k].low, 0, 255)), ps.hi = uchar(std::clamp(outs[k].high, 0, 255));
    ps.in.assign(size_t(nw) * 64, 0);
    ps.in_high.assign(size_t(nw) * 64, 0);
    ps.lo_bits.resize(size_t(nw));
    ps.hi_bits.resize(size_t(nw));
    ps.row_start.assign(size_t(H) + 1, 0);
  }
  std::memset(full, 255, P);
  for (uchar* r : c) r[0] = r[W + 1] = 255;
  for (uchar* r : e) r[0] = r[W + 1] = 0;

  for (int t = 0; t <= H + 1; ++t) {
    if (t < H) {  // contrast row t: the saturated difference (a byte max and subtraction)
      const uchar* g = gray.ptr<uchar>(t);
      const uchar* b = background.ptr<uchar>(t);
      uchar* o = c[t % 3] + 1;
      if (s > 0) {
        for (int x = 0; x < W; ++x) o[x] = uchar(std::max(g[x], b[x]) - b[x]);
      } else {
        for (int x = 0; x < W; ++x) o[x] = uchar(std::max(g[x], b[x]) - g[x]);
      }
    }
    const int ye = t - 1;  // eroded row ye: min over rows ye-1..ye+1, then over x-1..x+1
    if (ye >= 0 && ye < H) {
      const uchar* a = ye - 1 >= 0 ? c[(ye - 1) % 3] : full;
      const uchar* m = c[ye % 3];
      const uchar* z = ye + 1 < H ? c[(ye + 1) % 3] : full;
      for (size_t x = 0; x < P; ++x) tmp[x] = std::min(std::min(a[x], m[x]), z[x]);
      uchar* o = e[ye % 3] + 1;
      for (int x = 0; x < W; ++x) o[x] = std::min(std::min(tmp[x], tmp[x + 1]), tmp[x + 2]);
    }
    const int y = t - 2;  // opened row y: max over eroded rows y-1..y+1, then over x-1..x+1
    if (y < 0 || y >= H) continue;
    {
      const uchar* a = y - 1 >= 0 ? e[(y - 1) % 3] : zero.data();
      const uchar* m = e[y % 3];
      const uchar* z = y + 1 < H ? e[(y + 1) % 3] : zero.data();
      for (size_t x = 0; x < P; ++x) tmp[x] = std::max(std::max(a[x], m[x]), z[x]);
      uchar* op = opened.data();
      for (int x = 0; x < W; ++x) op[x] = std::max(std::max(tmp[x], tmp[x + 1]), tmp[x + 2]);
    }
    for (int k = 0; k < n_outs; ++k) {
      Pass& ps = passes[k];
      {
        const uchar* op = opened.data();
        uchar* il = ps.in.data();
        uchar* ih = ps.in_high.data();
        const uchar lo = ps.lo, hi = ps.hi;
        for (int x = 0; x < W; ++x) {
          const uchar o = op[x];
          il[x] = uchar(-int(o > lo));
          ih[x] = uchar(-int(o > lo && o > hi));
        }
      }
      // Runs above the low level, found 64 pixels at a time in the row's bits.
      std::vector<Run>& runs = ps.runs;
      ps.row_start[size_t(y)] = int(runs.size());
      pack_bits(ps.in.data(), nw, nullptr, ps.lo_bits.data());
      pack_bits(ps.in_high.data(), nw, ps.lo_bits.data(), ps.hi_bits.data());
      const uint64_t* lo_bits = ps.lo_bits.data();
      const uint64_t* hi_bits = ps.hi_bits.data();
      for (int i = 0; i < nw; ++i)
        if (hi_bits[i]) ps.above_high += __builtin_popcountll(hi_bits[i]);
      for (int x = next_bit(lo_bits, nw, 0, 0); x < W;) {
        const int end = next_bit(lo_bits, nw, x, ~0ULL);  // the padding is clear: end <= W
        runs.push_back(Run{y, x, end - 1, int(runs.size()), any_bit(hi_bits, x, end - 1)});
        x = next_bit(lo_bits, nw, end, 0);
      }
      // 8-connected to the previous row's runs: overlapping once widened by one pixel.
      if (y > 0) {
        int i = ps.row_start[size_t(y - 1)], j = ps.row_start[size_t(y)];
        const int i_end = ps.row_start[size_t(y)], j_end = int(runs.size());
        while (i < i_end && j < j_end) {
          const Run& p = runs[size_t(i)];
          const Run& q = runs[size_t(j)];
          if (p.x1 + 1 < q.x0) ++i;
          else if (q.x1 + 1 < p.x0) ++j;
          else {
            unite(runs, i, j);
            if (p.x1 < q.x1) ++i;
            else ++j;
          }
        }
      }
    }
  }
  for (int k = 0; k < n_outs; ++k) {
    passes[k].row_start[size_t(H)] = int(passes[k].runs.size());
    finish(passes[k], W, H, outs[k]);
  }
}

namespace {

struct KeptFrame {
  cv::Mat frame;
  std::vector<cv::Rect> written;
};
thread_local KeptFrame kept;

}  // namespace

cv::Mat label_frame(cv::Size size) {
  // (refcount 1: only `kept` refers to the pixels. OpenCV changes the count atomically; it is read atomically too,
  // so a holder releasing its copy on another thread is seen, without a data race.)
  if (!kept.frame.empty() && kept.frame.size() == size && kept.frame.u &&
      __atomic_load_n(&kept.frame.u->refcount, __ATOMIC_ACQUIRE) == 1) {
    for (const cv::Rect& r : kept.written) kept.frame(r).setTo(0);
  } else {
    kept.frame = cv::Mat(size, CV_32S, cv::Scalar(0));  // a new buffer (Mat::zeros would zero a held one in place)
  }
  kept.written.clear();
  return kept.frame;
}

void label_frame_written(const cv::Mat& frame, cv::Rect box) {
  if (frame.data != kept.frame.data || frame.size() != kept.frame.size()) return;
  box &= cv::Rect(0, 0, frame.cols, frame.rows);
  if (box.area() > 0) kept.written.push_back(box);
}

long long label_components(const cv::Mat& gray, const cv::Mat& background, int s, int low, int high, int first_label,
                           cv::Mat& labels, std::vector<Component>& comps, bool clear) {
  Labelling out{low, high, first_label, &labels, &comps, clear};
  label_components(gray, background, s, &out, 1);
  return out.above_high;
}

}  // namespace rbx1::vision
