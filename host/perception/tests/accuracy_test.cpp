// accuracy_test.cpp - orientation, centroid and grip opening on random noisy, blurred scenes against exact truth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "detector.hpp"
#include "image_io.hpp"
#include "pose.hpp"
#include "shapes.hpp"

namespace rbx1::vision {
namespace {

using namespace test;

double pct(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, size_t(p * (v.size() - 1) + 0.5))];
}

struct Errors {
  std::vector<double> orient, centroid, grip;
};

// Rectangles and ellipses (aspect 1.5-4) plus triangles and L shapes, random pose, both polarities.
Errors run_scenes(AxisSource source, int scenes) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(0, 1);
  Errors e;
  for (int n = 0; n < scenes; ++n) {
    Scene s;
    bool light = n % 2;
    s.background = light ? 50 : 190 + 20 * U(rng);
    s.object = light ? 170 + 40 * U(rng) : 50 + 30 * U(rng);
    s.noise_sigma = 2 + 4 * U(rng);
    s.blur_sigma = 0.5 + U(rng);
    s.light_gradient = 30 * (U(rng) - 0.5);
    s.seed = unsigned(n + 1);
    std::vector<Poly> polys;
    std::vector<double> angles;
    std::vector<bool> elong;
    for (int i = 0; i < 4; ++i) {
      cv::Point2d c(100 + 440 * (i % 2) + 40 * U(rng), 110 + 260 * (i / 2) + 30 * U(rng));
      double ang = 180 * U(rng) - 90, len = 50 + 60 * U(rng), aspect = 1.5 + 2.5 * U(rng);
      int kind = (n + i) % 4;
      if (kind == 0) polys.push_back(rectangle(c, len, len / aspect, ang));
      else if (kind == 1) polys.push_back(ellipse(c, len / 2, len / 2 / aspect, ang));
      else if (kind == 2) polys.push_back(triangle(c, len, ang));
      else polys.push_back(l_shape(c, len, len / 3, ang));
      angles.push_back(ang);
      elong.push_back(kind < 2);
    }
    Detection det;
    std::string err;
    DetectorOptions opt;
    opt.pose.source = source;
    if (!detect(to_gray8(render(s, polys)), cv::Mat(), opt, nullptr, det, err)) continue;
    for (size_t i = 0; i < polys.size(); ++i) {
      cv::Point2d c = poly_centroid(polys[i]);
      const DetectedObject* best = nullptr;
      for (const auto& o : det.objects)
        if (!best || cv::norm(o.geometry.centroid - c) < cv::norm(best->geometry.centroid - c)) best = &o;
      if (!best) {
        e.centroid.push_back(99);
        continue;
      }
      e.centroid.push_back(cv::norm(best->geometry.centroid - c));
      if (elong[i]) e.orient.push_back(std::abs(fold_axis_deg(best->pose.orientation_deg - angles[i])));
      e.grip.push_back(std::abs(best->grip.opening_px - min_chord(polys[i], c)));
    }
  }
  return e;
}

TEST(Accuracy, MeetsTheBenchmarkThresholdsOnDrawnScenes) {
  Errors e = run_scenes(AxisSource::Edges, 24);
  ASSERT_EQ(e.centroid.size(), 96u);
  std::printf("orientation (edge scatter): median %.3f p95 %.3f max %.3f deg (n=%zu)\n", pct(e.orient, 0.5),
              pct(e.orient, 0.95), pct(e.orient, 1), e.orient.size());
  std::printf("centroid: median %.3f p95 %.3f px; grip opening: median %.3f p95 %.3f px\n", pct(e.centroid, 0.5),
              pct(e.centroid, 0.95), pct(e.grip, 0.5), pct(e.grip, 0.95));
  EXPECT_LE(pct(e.orient, 0.5), 0.3);
  EXPECT_LE(pct(e.orient, 0.95), 1.0);
  EXPECT_LE(pct(e.centroid, 0.95), 0.5);
  EXPECT_LE(pct(e.grip, 0.95), 1.5);
}

TEST(Accuracy, AreaMomentAxisForComparison) {
  Errors e = run_scenes(AxisSource::Area, 24);
  std::printf("orientation (area moments): median %.3f p95 %.3f max %.3f deg\n", pct(e.orient, 0.5), pct(e.orient, 0.95),
              pct(e.orient, 1));
  EXPECT_LE(pct(e.orient, 0.95), 1.0);
}

}  // namespace
}  // namespace rbx1::vision
