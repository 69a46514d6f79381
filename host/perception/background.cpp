// background.cpp - background subtraction and automatic background modelling, both polarities.
#include "background.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>

#include <opencv2/imgproc.hpp>

namespace rbx1::vision {
namespace {

// Median and MAD-based sigma of gray - background (values within +-255), on a sparse grid for speed.
// window > 0: only differences within +-window count (the table, when objects may cover most of the frame).
void robust_stats(const cv::Mat& g, const cv::Mat& bg, int step, double& median, double& sigma, int window = 0) {
  // Counted into 4 histograms in turn (equal neighbours then do not wait on each other's count), then summed.
  std::array<std::array<int, 512>, 4> part{};
  int n = 0;
  for (int y = step / 2; y < g.rows; y += step) {
    const uchar* gr = g.ptr<uchar>(y);
    const uchar* br = bg.ptr<uchar>(y);
    for (int x = step / 2; x < g.cols; x += step) {
      const int d = gr[x] - br[x];
      if (window > 0 && std::abs(d) > window) continue;
      part[size_t(n & 3)][size_t(d + 256)]++;
      ++n;
    }
  }
  std::array<int, 512> hist{};
  for (size_t i = 0; i < 512; ++i) hist[i] = part[0][i] + part[1][i] + part[2][i] + part[3][i];
  if (n == 0) {
    median = 0, sigma = 1;
    return;
  }
  // The index of the median count of a histogram.
  auto median_index = [&](const std::array<int, 512>& h, int total) {
    int acc = 0;
    for (int i = 0; i < 512; ++i) {
      acc += h[size_t(i)];
      if (2 * acc >= total) return i;
    }
    return 0;
  };
  const int med = median_index(hist, n) - 256;
  // Absolute deviations from the median: 0..510 (a difference of -255 from a median of +255).
  std::array<int, 512> dev{};
  for (int i = 0; i < 512; ++i) dev[size_t(std::abs(i - 256 - med))] += hist[size_t(i)];
  const int mad = median_index(dev, n);
  median = med;
  sigma = std::max(1.0, 1.4826 * mad);
}

int sign_of(Polarity p) { return p == Polarity::Light ? +1 : -1; }

std::string size_text(const cv::Mat& m) { return std::to_string(m.cols) + "x" + std::to_string(m.rows); }

}  // namespace

bool average_background(const std::vector<cv::Mat>& frames, cv::Mat& out, std::string& error) {
  if (frames.empty()) {
    error = "no frames to average";
    return false;
  }
  const cv::Mat& f0 = frames.front();
  if (f0.empty() || (f0.depth() != CV_8U && f0.depth() != CV_16U)) {
    error = "frame 1 is empty or not 8/16-bit";
    return false;
  }
  cv::Mat acc(f0.size(), CV_MAKETYPE(CV_64F, f0.channels()), cv::Scalar::all(0));
  for (size_t i = 0; i < frames.size(); ++i) {
    const cv::Mat& f = frames[i];
    if (f.size() != f0.size() || f.type() != f0.type()) {
      error = "frame " + std::to_string(i + 1) + " is " + size_text(f) + " with " + std::to_string(f.channels()) +
              " channels, frame 1 is " + size_text(f0) + " with " + std::to_string(f0.channels());
      return false;
    }
    cv::accumulate(f, acc);
  }
  acc.convertTo(out, f0.type(), 1.0 / double(frames.size()));  // rounds to nearest
  return true;
}

// Without nth_element's unpredictable branches (a third of the light fit's time): non-negative floats' bit
// patterns order as the values do, so a radix select on 11 + 11 + 10 bits. An empty v has none (returns 0).
float kth_smallest(const std::vector<float>& v, size_t k) {
  uint32_t prefix = 0, mask = 0;
  for (const int shift : {21, 10, 0}) {
    const uint32_t digits = shift == 0 ? 1024 : 2048;
    std::array<uint32_t, 2048> hist{};
    for (float f : v) {
      uint32_t b;
      std::memcpy(&b, &f, 4);
      if ((b & mask) == prefix) hist[(b >> shift) & (digits - 1)]++;
    }
    uint32_t d = 0;
    while (d + 1 < digits && k >= hist[d]) k -= hist[d++];
    prefix |= d << shift;
    mask |= (digits - 1) << shift;
  }
  float f;
  std::memcpy(&f, &prefix, 4);
  return f;
}

LightFit compensate_light(const cv::Mat& gray, const cv::Mat& bg, cv::Mat* corrected) {
  CV_Assert(gray.type() == CV_8U && bg.type() == CV_8U && gray.size() == bg.size());
  // Samples on a grid of about 6 000 points, skipping saturated pixels (their ratio says nothing).
  const int step = std::max(1, int(std::sqrt(double(gray.total()) / 6000.0)));
  std::vector<float> b, g, clipped;  // clipped: the frame where the background is saturated white
  for (int y = step / 2; y < gray.rows; y += step) {
    const uchar* gr = gray.ptr<uchar>(y);
    const uchar* br = bg.ptr<uchar>(y);
    for (int x = step / 2; x < gray.cols; x += step) {
      if (gr[x] > 2 && gr[x] < 253 && br[x] > 2 && br[x] < 253) b.push_back(br[x]), g.push_back(gr[x]);
      else if (gr[x] > 2 && gr[x] < 253 && br[x] >= 253) clipped.push_back(gr[x]);
    }
  }
  LightFit fit;
  const size_t n = b.size();
  if (n < 50 && clipped.size() >= 50) {
    // An over-exposed white table captured as 255 everywhere: its true level is unknown, but the dimmer frame
    // shows where the table now is (issue 27: a frame a few per cent darker read the whole table as an object,
    // and nothing was found). The background is brought to the frame's median there (the table is most of it).
    const float med = kth_smallest(clipped, clipped.size() / 2);
    fit.gain = med / 255.0;
    size_t near = 0;
    for (float v : clipped) near += std::abs(v - med) <= 8;
    fit.unchanged = double(near) / double(clipped.size());
  } else if (n < 50) {
    return fit;
  }
  std::vector<char> use(n, 1);
  std::vector<float> res(n);
  for (int iter = 0; iter < 4 && n >= 50; ++iter) {
    double sb = 0, sg = 0, sbb = 0, sbg = 0, m = 0;
    for (size_t i = 0; i < n; ++i)
      if (use[i]) sb += b[i], sg += g[i], sbb += double(b[i]) * b[i], sbg += double(b[i]) * g[i], m += 1;
    if (m < 50) break;
    const double vb = sbb - sb * sb / m;
    if (vb >= 4.0 * m) {  // the table spans enough levels to tell gain from offset
      fit.gain = (sbg - sb * sg / m) / vb;
      fit.offset = (sg - fit.gain * sb) / m;
    } else {  // a nearly uniform table: light changes are multiplicative, fit the gain alone, as the median
      // ratio of the kept samples (the table is most of them). A least-squares gain is pulled by the objects,
      // and its residual cut then never leaves them out: a dark silhouette covering a quarter of a plain table
      // read as a gain of 0.85, the whole table as foreground ("frame is 100% foreground", issue 27).
      std::vector<float> ratio;
      ratio.reserve(size_t(m));
      for (size_t i = 0; i < n; ++i)
        if (use[i]) ratio.push_back(g[i] / b[i]);
      fit.gain = kth_smallest(ratio, ratio.size() / 2);
      fit.offset = 0;
    }
    fit.unchanged = m / double(n);
    // Residuals of every sample; unchanged pixels are those within 3 robust sigma of the fit.
    for (size_t i = 0; i < n; ++i) res[i] = std::abs(g[i] - float(fit.gain * b[i] + fit.offset));
    std::vector<float> kept;
    kept.reserve(n);
    for (size_t i = 0; i < n; ++i)
      if (use[i]) kept.push_back(res[i]);
    const float cut = std::max(4.0f, 3.0f * 1.4826f * kth_smallest(kept, kept.size() / 2));
    for (size_t i = 0; i < n; ++i) use[i] = res[i] <= cut;
  }
  // A plausible light change only (a lamp dimmed or brightened, the black level moved): anything larger is a
  // wrong background or a covered table, which isolation must report rather than have fitted away.
  if (!(fit.gain >= 0.5 && fit.gain <= 2.0 && std::abs(fit.offset) <= 64 && fit.unchanged >= 0.2)) fit = LightFit{};
  if (corrected) {
    cv::Mat out;  // never in place: *corrected may share the caller's background image
    if (fit.gain == 1 && fit.offset == 0) out = bg;  // no change: shared, not copied (callers never write it)
    else bg.convertTo(out, CV_8U, fit.gain, fit.offset);
    *corrected = out;
  }
  return fit;
}

bool contrast_from_background(const cv::Mat& gray, const cv::Mat& background_gray, Polarity objects, double min_contrast,
                              Contrast& out, std::string& error) {
  if (gray.size() != background_gray.size()) {
    error = "background is " + std::to_string(background_gray.cols) + "x" + std::to_string(background_gray.rows) +
            " but the frame is " + std::to_string(gray.cols) + "x" + std::to_string(gray.rows);
    return false;
  }
  out.gray = gray;
  out.background = background_gray;
  double median = 0;
  robust_stats(gray, background_gray, 3, median, out.noise_sigma);
  (void)min_contrast;
  out.sign = objects == Polarity::Auto ? 0 : sign_of(objects);  // auto: dark and light objects in one pass
  return true;
}

namespace {

// Quadratic surface fitted to the pixels of `cls` (least squares, a second round without the outliers); its
// robust residual spread in `resid`. false when too few pixels. The 6x6 normal equations, from the sums of
// u^i v^j (i + j <= 4) and of the grey times u^i v^j (i + j <= 2), accumulated row by row (the basis lies in
// [-1, 1], so they are well conditioned), solved by Cholesky: an SVD of the whole pixels x 6 system gave the
// same surface at 40 % of the automatic background's time.
bool fit_surface(const cv::Mat& small, const cv::Mat& cls, cv::Mat& coef, double& resid) {
  const double su = 2.0 / std::max(1, small.cols - 1), sv = 2.0 / std::max(1, small.rows - 1);
  cv::Mat use;
  cv::erode(cls, use, cv::Mat(), cv::Point(-1, -1), 1);  // away from the objects' blurred edges
  std::vector<double> u(size_t(small.cols)), res(small.total());
  for (int x = 0; x < small.cols; ++x) u[size_t(x)] = su * x - 1;
  std::vector<double> rv;
  for (int round = 0; round < 2; ++round) {
    double m[5][5] = {}, g[3][3] = {};  // m[i][j] = sum u^i v^j, g[i][j] = sum grey u^i v^j
    for (int y = 0; y < small.rows; ++y) {
      const uchar* ur = use.ptr<uchar>(y);
      const uchar* sr = small.ptr<uchar>(y);
      double r[5] = {}, rg[3] = {};  // this row's sums of u^i and of grey u^i
      for (int x = 0; x < small.cols; ++x) {
        if (!ur[x]) continue;
        const double a = u[size_t(x)], a2 = a * a, s = sr[x];
        r[0] += 1, r[1] += a, r[2] += a2, r[3] += a2 * a, r[4] += a2 * a2;
        rg[0] += s, rg[1] += s * a, rg[2] += s * a2;
      }
      if (r[0] == 0) continue;
      const double v = sv * y - 1;
      double vp = 1;
      for (int j = 0; j < 5; ++j, vp *= v) {
        for (int i = 0; i + j < 5; ++i) m[i][j] += r[i] * vp;
        for (int i = 0; i + j < 3; ++i) g[i][j] += rg[i] * vp;
      }
    }
    if (m[0][0] < 30) return false;
    // Basis 1, u, v, u^2, uv, v^2 as powers (i, j) of u and v.
    static constexpr int pu[6] = {0, 1, 0, 2, 1, 0}, pv[6] = {0, 0, 1, 0, 1, 2};
    cv::Matx66d ata;
    cv::Vec6d atb;
    for (int i = 0; i < 6; ++i) {
      atb[i] = g[pu[i]][pv[i]];
      for (int j = 0; j < 6; ++j) ata(i, j) = m[pu[i] + pu[j]][pv[i] + pv[j]];
    }
    cv::Mat c;
    if (!cv::solve(cv::Mat(ata), cv::Mat(atb), c, cv::DECOMP_CHOLESKY) &&
        !cv::solve(cv::Mat(ata), cv::Mat(atb), c, cv::DECOMP_SVD))
      return false;
    coef = c;
    const double* k = c.ptr<double>();
    rv.clear();
    for (int y = 0; y < small.rows; ++y) {  // the surface along a row: a quadratic in u
      const double v = sv * y - 1, c0 = k[0] + k[2] * v + k[5] * v * v, c1 = k[1] + k[4] * v;
      const uchar* ur = use.ptr<uchar>(y);
      const uchar* sr = small.ptr<uchar>(y);
      double* rr = res.data() + size_t(y) * size_t(small.cols);
      for (int x = 0; x < small.cols; ++x) {
        if (!ur[x]) continue;
        const double a = u[size_t(x)];
        rv.push_back(rr[x] = std::abs(c0 + c1 * a + k[3] * a * a - sr[x]));
      }
    }
    std::nth_element(rv.begin(), rv.begin() + long(rv.size() / 2), rv.end());
    resid = 1.4826 * rv[rv.size() / 2];
    for (int y = 0; y < small.rows; ++y) {  // second round: only the pixels that fit (drops a shadow or a pattern patch)
      uchar* ur = use.ptr<uchar>(y);
      const double* rr = res.data() + size_t(y) * size_t(small.cols);
      for (int x = 0; x < small.cols; ++x)
        if (ur[x] && rr[x] > 3 * resid + 2) ur[x] = 0;
    }
  }
  return true;
}

// Share of the low-resolution frame's outermost ring in the class (the table runs under the frame's edges,
// objects lie inside it: those cut by the edge are dropped anyway).
double border_share(const cv::Mat& cls) {
  int in = 0, n = 0;
  for (int x = 0; x < cls.cols; ++x) in += (cls.at<uchar>(0, x) > 0) + (cls.at<uchar>(cls.rows - 1, x) > 0), n += 2;
  for (int y = 1; y + 1 < cls.rows; ++y) in += (cls.at<uchar>(y, 0) > 0) + (cls.at<uchar>(y, cls.cols - 1) > 0), n += 2;
  return n ? double(in) / n : 0;
}

// Connected pieces of the class (8-connected, at least 4 px of the low-resolution frame).
int pieces_of(const cv::Mat& cls) {
  cv::Mat lab, stats, centres;
  const int n = cv::connectedComponentsWithStats(cls, lab, stats, centres, 8, CV_32S);
  int out = 0;
  for (int i = 1; i < n; ++i) out += stats.at<int>(i, cv::CC_STAT_AREA) >= 4;
  return out;
}

// The global model: Otsu splits the low-resolution frame in two classes. Either class covering at least 30 %
// of the frame may be the table (a light box in a dark frame, a tray more than half covered); with the
// objects' polarity given, only the class on the other side of it, from 10 % of the frame (dark objects
// covering most of the frame: issue 27, six squares on white all lost from 30.4 % coverage, where the squares'
// class fitted the surface as well as the table's and was taken for it). Of the classes left, the one a smooth
// (quadratic) surface fits best is the table (a table is smooth; objects have relief, edges, several levels);
// when both fit alike (residuals within kFitsAlike), the one in fewer pieces (the table is one, the objects
// several: pca_test1.jpg's light box holds six propellers, its dark frame is a seventh piece of their class),
// then the one holding more of the frame's border, and when that is even too (within 0.2), the choice is noted
// as a guess. The pieces say nothing about a crowd: touching objects are one piece and the table showing
// between them is many (water_coins.jpg: its coins one piece, the white scan fifteen), so the fit must decide
// wherever it can.
// Residuals within this ratio (plus 0.5 levels) fit alike. Measured on the corpus photos lit 0.80-1.20x and
// -10/0/+10 levels: a table fits 1.55-1.75x better than its objects (water_coins.jpg's white scan against its
// coins' relief, pca_test1.jpg's light box against its propellers and dark frame), except where the objects'
// class is clipped to black (pca_test1.jpg at -10 levels: the frame fits 1.09x better, flattened): at 1.5x,
// water_coins.jpg's crowd (1.62-1.64x) was taken for the table at 0.90 and at +10 levels (0 of 20 coins, 11
// phantoms). 1.3 lies between (their geometric mean is 1.33); the generated scenes never have two classes
// that fit (their objects cover under 30 %).
constexpr double kFitsAlike = 1.3;
bool global_background(const cv::Mat& small, int sign, cv::Mat& surface, double& sep_out, std::string& note) {
  cv::Mat hi;
  cv::threshold(small, hi, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
  cv::Scalar mean_all, sd_all;
  cv::meanStdDev(small, mean_all, sd_all);
  int n_hi = cv::countNonZero(hi), n = int(small.total()), n_lo = n - n_hi;
  if (n_hi == 0 || n_lo == 0 || sd_all[0] < 4) return false;
  double m_hi = cv::mean(small, hi)[0], m_lo = cv::mean(small, ~hi)[0];
  double w_hi = double(n_hi) / n, w_lo = double(n_lo) / n;
  double between = w_hi * w_lo * (m_hi - m_lo) * (m_hi - m_lo), total = sd_all[0] * sd_all[0];
  if (between < 0.75 * total) return false;  // not bimodal enough
  const double sep = std::abs(m_hi - m_lo);
  sep_out = sep;
  const double limit = std::max(3.0, sep / 8);
  struct Fit { cv::Mat coef; double resid = 1e300, border = 0; int pieces = 0; };
  std::vector<Fit> fits;
  const cv::Mat lo = ~hi;
  for (int c = 0; c < 2; ++c) {
    const cv::Mat& cls = c == 0 ? hi : lo;
    if (sign != 0 && (c == 0) != (sign < 0)) continue;  // dark objects: the table is the lighter class
    Fit f;
    if (double(cv::countNonZero(cls)) < (sign != 0 ? 0.1 : 0.3) * n || !fit_surface(small, cls, f.coef, f.resid) ||
        f.resid > limit)
      continue;
    f.border = border_share(cls);
    f.pieces = pieces_of(cls);
    fits.push_back(f);
  }
  if (fits.empty()) return false;  // uneven or patterned: local model
  size_t best = 0;
  if (fits.size() == 2) {
    const double r0 = fits[0].resid, r1 = fits[1].resid;
    if (std::max(r0, r1) > kFitsAlike * std::min(r0, r1) + 0.5) {
      best = r1 < r0;
    } else if (fits[0].pieces != fits[1].pieces) {
      best = fits[1].pieces < fits[0].pieces;  // the table is one piece, the objects several
    } else {
      best = fits[1].border > fits[0].border;
      if (std::abs(fits[0].border - fits[1].border) < 0.2)
        note = "automatic background: the table could be the lighter or the darker half of the frame (both fit "
               "a smooth surface and reach the frame's edges alike); took the " +
               std::string(best == 0 ? "lighter" : "darker") + " one: give --objects dark|light or --background";
    }
  }
  const double* c = fits[best].coef.ptr<double>();
  surface.create(small.size(), CV_32F);
  for (int y = 0; y < small.rows; ++y)
    for (int x = 0; x < small.cols; ++x) {
      double u = 2.0 * x / std::max(1, small.cols - 1) - 1, v = 2.0 * y / std::max(1, small.rows - 1) - 1;
      surface.at<float>(y, x) = float(c[0] + c[1] * u + c[2] * v + c[3] * u * u + c[4] * u * v + c[5] * v * v);
    }
  return true;
}

}  // namespace

void contrast_auto(const cv::Mat& gray, Polarity objects, double min_contrast, Contrast& out) {
  // Work at about 160 px across: the background is smooth at that scale, objects are not.
  const int f = std::max(1, int(std::ceil(std::max(gray.cols, gray.rows) / 160.0)));
  cv::Mat small;
  cv::resize(gray, small, cv::Size((gray.cols + f - 1) / f, (gray.rows + f - 1) / f), 0, 0, cv::INTER_AREA);
  cv::Mat bsmall;
  int sign = objects == Polarity::Auto ? 0 : sign_of(objects);
  double sep = 0;
  out.global_model = global_background(small, sign, bsmall, sep, out.note);
  if (!out.global_model) {
    int k = std::max(3, (std::min(small.cols, small.rows) / 3) | 1);
    k = std::min(k, 255);
    cv::Mat b0;
    cv::medianBlur(small, b0, k);

    // First guess of the objects at low resolution, to exclude them from the second estimate.
    cv::Mat r;
    cv::subtract(small, b0, r, cv::noArray(), CV_16S);
    double med = 0, sig = 1;
    robust_stats(small, b0, 1, med, sig);
    double t = std::max(min_contrast, 4 * sig);
    cv::Mat objmask, lo, hi;
    cv::compare(r, med + t / 2, hi, cv::CMP_GT);
    cv::compare(r, med - t / 2, lo, cv::CMP_LT);
    objmask = sign > 0 ? hi : sign < 0 ? lo : (hi | lo);
    cv::dilate(objmask, objmask, cv::Mat(), cv::Point(-1, -1), 1);

    // Normalised convolution: average of background pixels only, with a wide Gaussian.
    cv::Mat w, v, num, den;
    objmask.convertTo(w, CV_32F, -1.0 / 255.0, 1.0);
    small.convertTo(v, CV_32F);
    v = v.mul(w);
    double sigma_blur = std::max(1.0, k / 4.0);
    cv::GaussianBlur(v, num, cv::Size(), sigma_blur);
    cv::GaussianBlur(w, den, cv::Size(), sigma_blur);
    bsmall.create(small.size(), CV_32F);
    for (int y = 0; y < small.rows; ++y) {
      const float* n = num.ptr<float>(y);
      const float* d = den.ptr<float>(y);
      const uchar* fb = b0.ptr<uchar>(y);
      float* o = bsmall.ptr<float>(y);
      for (int x = 0; x < small.cols; ++x) o[x] = d[x] > 0.05f ? n[x] / d[x] : float(fb[x]);
    }
  }
  cv::Mat s8, b8;
  bsmall.convertTo(s8, CV_8U);
  cv::resize(s8, b8, gray.size(), 0, 0, cv::INTER_LINEAR);
  out.gray = gray;
  out.background = b8;
  out.modelled = true;
  double median = 0;
  // With the global model the objects may cover most of the frame: the noise is measured on the table only.
  robust_stats(gray, b8, 4, median, out.noise_sigma, out.global_model ? std::max(8, int(sep / 2)) : 0);
  out.sign = sign;
}

}  // namespace rbx1::vision
