// grip_test.cpp - step V: D(theta) minimum, real contacts on non-convex objects, finger clearance, feasibility.
#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/imgproc.hpp>

#include "detector.hpp"
#include "grip.hpp"
#include "image_io.hpp"
#include "pose.hpp"
#include "shapes.hpp"

namespace rbx1::vision {
namespace {

using namespace test;

Detection run(const std::vector<Poly>& polys, double finger_w = 0, double finger_d = 0) {
  Scene s;
  s.noise_sigma = 2, s.blur_sigma = 0.7;
  DetectorOptions o;
  o.grip.finger_width_px = finger_w;
  o.grip.finger_depth_px = finger_d;
  Detection d;
  std::string e;
  EXPECT_TRUE(detect(to_gray8(render(s, polys)), {}, o, nullptr, d, e)) << e;
  return d;
}

// Distance from p to the polygon's boundary.
double to_boundary(const Poly& poly, cv::Point2d p) {
  double best = 1e300;
  for (size_t i = 0; i < poly.size(); ++i) {
    cv::Point2d a = poly[i], b = poly[(i + 1) % poly.size()], d = b - a;
    double t = std::clamp((p - a).dot(d) / d.dot(d), 0.0, 1.0);
    best = std::min(best, cv::norm(a + t * d - p));
  }
  return best;
}

TEST(Grip, RectangleIsGrippedAcrossItsWidth) {
  Poly r = rectangle({300, 240}, 160, 50, 25);
  Detection d = run({r});
  ASSERT_EQ(d.objects.size(), 1u);
  const Grip& g = d.objects[0].grip;
  EXPECT_NEAR(g.opening_px, 50, 0.5);
  EXPECT_NEAR(std::abs(fold_axis_deg(g.angle_deg - 25)), 90, 1.5);
  EXPECT_LT(to_boundary(r, g.p1), 0.5);
  EXPECT_LT(to_boundary(r, g.p2), 0.5);
  // p1 -> p2 is the closing direction in (-90, 90].
  EXPECT_NEAR(std::atan2(g.p2.y - g.p1.y, g.p2.x - g.p1.x) * 180 / M_PI, g.angle_deg, 0.01);
}

TEST(Grip, NonConvexObjectGetsOutermostContactsNotConcavityHits) {
  // A U shape: the paper's r(theta) + r(theta + pi) from the first ray hits would close inside the notch.
  Poly u = {{200, 180}, {330, 180}, {330, 300}, {290, 300}, {290, 220}, {240, 220}, {240, 300}, {200, 300}};
  cv::Point2d c = poly_centroid(u);
  Detection d = run({u});
  ASSERT_EQ(d.objects.size(), 1u);
  const Grip& g = d.objects[0].grip;
  EXPECT_NEAR(g.opening_px, min_chord(u, c), 1.0);
  EXPECT_LT(to_boundary(u, g.p1), 0.6);
  EXPECT_LT(to_boundary(u, g.p2), 0.6);
  // The fingers close from outside: nothing of the object lies beyond either contact along the line.
  cv::Point2d dir = (g.p2 - g.p1) / cv::norm(g.p2 - g.p1);
  std::vector<cv::Point2f> uf;
  for (auto v : u) uf.emplace_back(float(v.x), float(v.y));
  for (double t = 1.5; t < 80; t += 1) {
    EXPECT_LT(cv::pointPolygonTest(uf, cv::Point2f(g.p2 + t * dir), false), 0);
    EXPECT_LT(cv::pointPolygonTest(uf, cv::Point2f(g.p1 - t * dir), false), 0);
  }
}

TEST(Grip, OpeningMatchesTheChordDefinitionOnManyShapes) {
  std::vector<Poly> shapes = {ellipse({150, 130}, 60, 25, 70), triangle({450, 130}, 100, -20), l_shape({150, 340}, 110, 35, 33),
                              star({450, 340}, 60, 30, 5, 12)};
  Detection d = run(shapes);
  ASSERT_EQ(d.objects.size(), 4u);
  for (const Poly& p : shapes) {
    cv::Point2d c = poly_centroid(p);
    const DetectedObject* o = nullptr;
    for (const auto& x : d.objects)
      if (cv::norm(x.geometry.centroid - c) < 2) o = &x;
    ASSERT_TRUE(o);
    EXPECT_NEAR(o->grip.opening_px, min_chord(p, c), 1.5);
  }
}

TEST(Grip, FingerDoesNotLandOnANeighbour) {
  // A bar with a block parked 6 px beside its long side: the narrow grip would put a finger on the block.
  Poly bar = rectangle({300, 240}, 150, 40, 0), block = rectangle({300, 286}, 60, 40, 0);
  Detection free = run({bar, block});
  Detection fingers = run({bar, block}, 14, 14);
  ASSERT_EQ(free.objects.size(), 2u);
  ASSERT_EQ(fingers.objects.size(), 2u);
  const Grip& g0 = free.objects[0].grip;
  const Grip& g1 = fingers.objects[0].grip;
  EXPECT_NEAR(std::abs(g0.angle_deg), 90, 2);  // across the bar, straight onto the block
  EXPECT_TRUE(g1.clear);
  EXPECT_GT(std::abs(fold_axis_deg(g1.angle_deg - g0.angle_deg)), 20);  // a different, clear direction
  // The chosen contacts are clear of the block by the finger's half width.
  for (cv::Point2d p : {g1.p1, g1.p2}) EXPECT_LT(to_boundary(bar, p), 1.0);
}

TEST(Grip, NoClearGripIsInfeasible) {
  // A disc boxed in on all sides by close neighbours.
  std::vector<Poly> polys = {ellipse({300, 240}, 30, 30, 0)};
  for (int i = 0; i < 12; ++i) {
    double a = i * M_PI / 6;
    polys.push_back(ellipse({300 + 44 * std::cos(a), 240 + 44 * std::sin(a)}, 9, 9, 0));
  }
  Detection d = run(polys, 12, 12);
  const DetectedObject* disc = nullptr;
  for (const auto& o : d.objects)
    if (cv::norm(o.geometry.centroid - cv::Point2d(300, 240)) < 1) disc = &o;
  ASSERT_TRUE(disc);
  EXPECT_FALSE(disc->grip.clear);
}

}  // namespace
}  // namespace rbx1::vision
