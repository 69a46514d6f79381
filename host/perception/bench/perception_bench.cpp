// perception_bench.cpp - speed of the full method against a plain OpenCV pipeline and a literal per-layer
// implementation of the paper, on the same synthetic frames, one core (tools/bench/perception-speed runs it).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "detector.hpp"
#include "image_io.hpp"

namespace {

using namespace rbx1::vision;

// A frame of n objects (bars, ellipses, triangles) on a grid, light table, blur and sensor noise.
const cv::Mat& frame(int w, int h, int n) {
  static std::map<std::tuple<int, int, int>, cv::Mat> cache;
  auto key = std::make_tuple(w, h, n);
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  cv::Mat img(h, w, CV_8UC3, cv::Scalar::all(200));
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> U(0, 1);
  int cols = int(std::ceil(std::sqrt(n * double(w) / h))), rows = (n + cols - 1) / cols;
  double cw = double(w) / cols, ch = double(h) / rows, s = std::min(cw, ch) * 0.6;
  for (int i = 0; i < n; ++i) {
    cv::Point2d c((i % cols + 0.5) * cw + (U(rng) - 0.5) * cw * 0.1, (i / cols + 0.5) * ch + (U(rng) - 0.5) * ch * 0.1);
    double a = U(rng) * 180;
    cv::Scalar fg = cv::Scalar::all(50 + 30 * U(rng));
    if (i % 3 == 0) {
      cv::Point2f p[4];
      cv::RotatedRect(cv::Point2f(c), cv::Size2f(float(s), float(s * 0.35)), float(a)).points(p);
      std::vector<cv::Point> q;
      for (auto& v : p) q.emplace_back(int(v.x * 16), int(v.y * 16));
      cv::fillPoly(img, std::vector<std::vector<cv::Point>>{q}, fg, cv::LINE_AA, 4);
    } else if (i % 3 == 1) {
      cv::ellipse(img, cv::RotatedRect(cv::Point2f(c), cv::Size2f(float(s * 0.9), float(s * 0.5)), float(a)), fg, -1, cv::LINE_AA);
    } else {
      std::vector<cv::Point> q;
      for (int k = 0; k < 3; ++k) {
        double t = a * M_PI / 180 + k * 2 * M_PI / 3;
        q.emplace_back(int((c.x + s * 0.45 * std::cos(t)) * 16), int((c.y + s * 0.45 * std::sin(t)) * 16));
      }
      cv::fillPoly(img, std::vector<std::vector<cv::Point>>{q}, fg, cv::LINE_AA, 4);
    }
  }
  cv::GaussianBlur(img, img, cv::Size(), 0.8);
  cv::Mat noise(img.size(), CV_16SC3);
  cv::randn(noise, 0, 4);
  cv::Mat out;
  img.convertTo(out, CV_16SC3);
  out += noise;
  out.convertTo(img, CV_8UC3);
  return cache[key] = img;
}

// The empty table of frame(): same light and blur, its own sensor noise (a second exposure).
const cv::Mat& empty_table(int w, int h) {
  static std::map<std::pair<int, int>, cv::Mat> cache;
  auto key = std::make_pair(w, h);
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  cv::Mat img(h, w, CV_8UC3, cv::Scalar::all(200)), noise(img.size(), CV_16SC3), out;
  cv::theRNG().state = 7;
  cv::randn(noise, 0, 4);
  img.convertTo(out, CV_16SC3);
  out += noise;
  out.convertTo(img, CV_8UC3);
  return cache[key] = to_gray8(img);
}

// The full method; with_background: the paper's isolation (subtracting the known empty scene, as the bundled
// config does), else the background modelled from the frame itself.
void full(benchmark::State& st, bool with_background) {
  cv::setNumThreads(1);
  int w = int(st.range(0)), h = int(st.range(1));
  const cv::Mat& img = frame(w, h, int(st.range(2)));
  cv::Mat background = with_background ? empty_table(w, h) : cv::Mat();
  DetectorOptions opt;
  size_t found = 0;
  for (auto _ : st) {
    Detection det;
    std::string err;
    detect(to_gray8(img), background, opt, nullptr, det, err);
    found = det.objects.size();
    benchmark::DoNotOptimize(det);
  }
  st.counters["objects"] = double(found);
}

void BM_Full(benchmark::State& st) { full(st, true); }
void BM_FullAutoBackground(benchmark::State& st) { full(st, false); }

// Baseline 1: threshold, connectedComponentsWithStats, findContours, minAreaRect.
void BM_OpenCV(benchmark::State& st) {
  cv::setNumThreads(1);
  const cv::Mat& img = frame(int(st.range(0)), int(st.range(1)), int(st.range(2)));
  size_t found = 0;
  for (auto _ : st) {
    cv::Mat gray, bin, labels, stats, cents;
    cv::cvtColor(img, gray, cv::COLOR_BGR2GRAY);
    cv::threshold(gray, bin, 0, 255, cv::THRESH_BINARY_INV | cv::THRESH_OTSU);
    int n = cv::connectedComponentsWithStats(bin, labels, stats, cents, 8, CV_32S);
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(bin, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
    std::vector<cv::RotatedRect> boxes;
    for (const auto& c : contours)
      if (c.size() > 20) boxes.push_back(cv::minAreaRect(c));
    found = boxes.size();
    benchmark::DoNotOptimize(n);
    benchmark::DoNotOptimize(boxes);
  }
  st.counters["objects"] = double(found);
}

// Baseline 2: the paper taken literally: binary image by subtracting the known uniform background, region
// growing, one full-frame layer per object, the gradient over each whole layer, edge points, eigenvector
// line fit, r-theta sort and D_i = r(theta_i) + r(theta_i + pi).
void BM_PaperLiteral(benchmark::State& st) {
  cv::setNumThreads(1);
  const cv::Mat& img = frame(int(st.range(0)), int(st.range(1)), int(st.range(2)));
  size_t found = 0;
  for (auto _ : st) {
    cv::Mat gray, bin, labels;
    cv::cvtColor(img, gray, cv::COLOR_BGR2GRAY);
    cv::Mat diff;
    cv::absdiff(gray, cv::Scalar(200), diff);
    cv::threshold(diff, bin, 40, 255, cv::THRESH_BINARY);
    int n = cv::connectedComponents(bin, labels, 8, CV_32S);
    found = 0;
    for (int i = 1; i < n; ++i) {
      cv::Mat layer;
      cv::compare(labels, i, layer, cv::CMP_EQ);
      cv::Mat gx, gy, mag;
      cv::Sobel(layer, gx, CV_32F, 1, 0);
      cv::Sobel(layer, gy, CV_32F, 0, 1);
      cv::magnitude(gx, gy, mag);
      std::vector<cv::Point> pts;
      cv::findNonZero(mag > 100, pts);
      if (pts.size() < 20) continue;
      double mx = 0, my = 0;
      for (auto& p : pts) mx += p.x, my += p.y;
      mx /= double(pts.size()), my /= double(pts.size());
      Eigen::Matrix2d S = Eigen::Matrix2d::Zero();
      std::vector<std::pair<double, double>> tr;
      for (auto& p : pts) {
        Eigen::Vector2d v(p.x - mx, p.y - my);
        S += v * v.transpose();
        tr.emplace_back(std::atan2(v.y(), v.x()), v.norm());
      }
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(S);
      std::sort(tr.begin(), tr.end());
      double dmin = 1e300;
      for (size_t k = 0; k < tr.size() / 2 + 1; ++k) {
        double opp = tr[k].first + M_PI;
        if (opp > M_PI) opp -= 2 * M_PI;
        auto it = std::lower_bound(tr.begin(), tr.end(), std::make_pair(opp, -1.0));
        if (it == tr.end()) it = tr.begin();
        dmin = std::min(dmin, tr[k].second + it->second);
      }
      benchmark::DoNotOptimize(es.eigenvectors());
      benchmark::DoNotOptimize(dmin);
      ++found;
    }
  }
  st.counters["objects"] = double(found);
}

void sizes(benchmark::internal::Benchmark* b) {
  for (auto [w, h] : {std::pair{640, 480}, {1280, 720}, {1920, 1080}})
    for (int n : {1, 5, 20}) b->Args({w, h, n});
  b->Args({1280, 720, 10});  // the target case
  b->Unit(benchmark::kMillisecond);
}

BENCHMARK(BM_Full)->Apply(sizes);
BENCHMARK(BM_FullAutoBackground)->Apply(sizes);
BENCHMARK(BM_OpenCV)->Apply(sizes);
BENCHMARK(BM_PaperLiteral)->Apply(sizes);

}  // namespace

BENCHMARK_MAIN();
