// grip_test.cpp - step V: D(theta) minimum, real contacts on non-convex objects, finger clearance, feasibility.
#include <gtest/gtest.h>

#include <cmath>
#include <optional>

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

// A disc (radius 30 px at 300, 240) boxed in on all sides by 12 close neighbours, detected with 12 px fingers: the
// disc's object, or nothing if it was not found.
std::optional<DetectedObject> boxed_in_disc() {
  std::vector<Poly> polys = {ellipse({300, 240}, 30, 30, 0)};
  for (int i = 0; i < 12; ++i) {
    double a = i * M_PI / 6;
    polys.push_back(ellipse({300 + 44 * std::cos(a), 240 + 44 * std::sin(a)}, 9, 9, 0));
  }
  Detection d = run(polys, 12, 12);
  for (const auto& o : d.objects)
    if (cv::norm(o.geometry.centroid - cv::Point2d(300, 240)) < 1) return o;
  return std::nullopt;
}

// The narrowest chord through pt whose outermost crossings lie on both sides of pt (0.05-degree steps).
double min_chord_two_sided(const Poly& poly, cv::Point2d pt) {
  double best = 1e300;
  for (int k = 0; k < 3600; ++k) {
    double phi = k * M_PI / 3600;
    cv::Point2d u(std::cos(phi), std::sin(phi));
    double lo = 1e300, hi = -1e300;
    for (size_t i = 0; i < poly.size(); ++i) {
      cv::Point2d a = poly[i] - pt, d = poly[(i + 1) % poly.size()] - poly[i];
      double den = u.x * d.y - u.y * d.x;
      if (std::abs(den) < 1e-12) continue;
      double s = (a.x * u.y - a.y * u.x) / den;
      if (s < 0 || s > 1) continue;
      double t = (a.x * d.y - a.y * d.x) / den;
      lo = std::min(lo, t), hi = std::max(hi, t);
    }
    if (lo < 0 && hi > 0) best = std::min(best, hi - lo);
  }
  return best;
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

// Does a finger (fw across the closing line, fd outward from contact q, beyond an edge band of `band` px: a
// blurred sharp tip comes out up to ~1.5 px short) cover any point of the polygon?
bool finger_on(const Poly& poly, cv::Point2d q, cv::Point2d out, double fw, double fd, double band) {
  std::vector<cv::Point2f> pf;
  for (auto v : poly) pf.emplace_back(float(v.x), float(v.y));
  cv::Point2d n(-out.y, out.x);
  for (double a = band; a <= fd; a += 0.5)
    for (double b = -fw / 2; b <= fw / 2; b += 0.5)
      if (cv::pointPolygonTest(pf, cv::Point2f(q + a * out + b * n), false) >= 0) return true;
  return false;
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
  // A U shape: the paper's r(theta) + r(theta + pi) from the first ray hits would close inside the notch. Its
  // centroid lies in the notch, so the bridge alone (crossed on one side of the centroid only) is no grip:
  // the fingers take the narrowest line with contacts on both sides.
  Poly u = {{200, 180}, {330, 180}, {330, 300}, {290, 300}, {290, 220}, {240, 220}, {240, 300}, {200, 300}};
  cv::Point2d c = poly_centroid(u);
  Detection d = run({u});
  ASSERT_EQ(d.objects.size(), 1u);
  const Grip& g = d.objects[0].grip;
  EXPECT_TRUE(g.feasible);
  EXPECT_LT(min_chord(u, c), 45);  // the old one-sided answer: the bridge, 40 px
  EXPECT_NEAR(g.opening_px, min_chord_two_sided(u, c), 1.0);
  EXPECT_LT((g.p1 - c).dot(g.p2 - c), 0);  // contacts on opposite sides of the centroid
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
  // The fingers come down off the bar too (they close on its outermost points within their width).
  cv::Point2d u = (g1.p2 - g1.p1) / cv::norm(g1.p2 - g1.p1);
  EXPECT_FALSE(finger_on(bar, g1.p1, -u, 14, 14, 0.75));
  EXPECT_FALSE(finger_on(bar, g1.p2, u, 14, 14, 0.75));
  for (cv::Point2d p : {g1.p1, g1.p2}) EXPECT_LT(to_boundary(bar, p), 7.0);
}

// Extent along u (through c) of the polygon's part within |across| <= half of that line: where fingers of
// that width stop when they close along it (the polygon's edges sampled every 0.05 px).
void band_extent(const Poly& poly, cv::Point2d c, cv::Point2d u, double half, double& lo, double& hi) {
  cv::Point2d n(-u.y, u.x);
  lo = 1e300, hi = -1e300;
  for (size_t i = 0; i < poly.size(); ++i) {
    cv::Point2d a = poly[i], d = poly[(i + 1) % poly.size()] - a;
    int steps = std::max(1, int(cv::norm(d) / 0.05));
    for (int s = 0; s <= steps; ++s) {
      cv::Point2d p = a + d * (double(s) / steps) - c;
      if (std::abs(p.dot(n)) > half) continue;
      lo = std::min(lo, p.dot(u)), hi = std::max(hi, p.dot(u));
    }
  }
}

TEST(Grip, FingersStayOffTheObjectsOwnOutline) {
  // The narrowest chord through the centroid of a star (tip to notch) and of an L (across one arm, beside the
  // other) puts a finger of real width on the object itself: the star's neighbouring points, the L's other arm.
  // The fingers must come down outside the object, around the centroid where the planner centres them.
  const double fw = 30, fd = 12;
  std::vector<Poly> shapes = {star({170, 200}, 80, 40, 5, 12), l_shape({460, 240}, 120, 40, 30)};
  Detection d = run(shapes, fw, fd);
  ASSERT_EQ(d.objects.size(), 2u);
  for (const Poly& p : shapes) {
    cv::Point2d c = poly_centroid(p);
    const DetectedObject* o = nullptr;
    for (const auto& x : d.objects)
      if (cv::norm(x.geometry.centroid - c) < 2) o = &x;
    ASSERT_TRUE(o);
    const Grip& g = o->grip;
    EXPECT_TRUE(g.feasible);
    cv::Point2d u = (g.p2 - g.p1) / cv::norm(g.p2 - g.p1);
    EXPECT_FALSE(finger_on(p, g.p1, -u, fw, fd, 1.5));
    EXPECT_FALSE(finger_on(p, g.p2, u, fw, fd, 1.5));
    // The gripper is centred on the centroid (the planner puts it there): both fingers open to the object's
    // farther extent within their width along the closing line, so the finger on the far side clears it too.
    double lo, hi;
    band_extent(p, o->geometry.centroid, u, fw / 2, lo, hi);
    EXPECT_NEAR(g.opening_px, 2 * std::max(hi, -lo), 1.5);
    EXPECT_LT(cv::norm((g.p1 + g.p2) / 2 - o->geometry.centroid), 1e-6);
  }
  // The chord-only grip (no finger size) of the same shapes does put a finger on them: the checks above can fail.
  Detection naive = run(shapes);
  for (const auto& o : naive.objects) {
    const Grip& g = o.grip;
    cv::Point2d u = (g.p2 - g.p1) / cv::norm(g.p2 - g.p1);
    double lo, hi;
    const Poly& p = cv::norm(o.geometry.centroid - poly_centroid(shapes[0])) < 2 ? shapes[0] : shapes[1];
    band_extent(p, o.geometry.centroid, u, fw / 2, lo, hi);
    EXPECT_GT(hi - lo, g.opening_px + 5) << "the naive grip of object " << o.index << " already leaves room";
    EXPECT_TRUE(finger_on(p, g.p1, -u, fw, fd, 1.5) || finger_on(p, g.p2, u, fw, fd, 1.5));
  }
}

TEST(Grip, NoClearGripIsInfeasible) {
  std::optional<DetectedObject> disc = boxed_in_disc();
  ASSERT_TRUE(disc);
  EXPECT_FALSE(disc->grip.clear);
}

}  // namespace
}  // namespace rbx1::vision

namespace rbx1::vision {
namespace {

using namespace test;

// A geometry whose contour is the polygon itself, densified to 0.5 px steps like a measured contour (no
// isolation), centroid set by hand.
Geometry polygon_geometry(const Poly& p, cv::Point2d centroid) {
  Geometry g;
  g.centroid = centroid;
  for (size_t i = 0; i < p.size(); ++i) {
    cv::Point2d a = p[i], b = p[(i + 1) % p.size()];
    int n = std::max(1, int(std::ceil(cv::norm(b - a) / 0.5)));
    for (int k = 0; k < n; ++k) g.contour.push_back({a.x + (b.x - a.x) * k / n, a.y + (b.y - a.y) * k / n, 1});
  }
  return g;
}

Grip grip_of(const Geometry& g, const GripOptions& o) {
  std::vector<double> phi, d;
  return choose_grip(g, cast_rays(g, o.lines), 0, cv::Mat(), {}, o, phi, d);
}

TEST(GripSafety, CentroidOutsideTheObjectHasNoOneSidedZeroWidthGrip) {
  // A thin arc (a C) whose centroid lies outside it: lines through the centroid cross the arc on one side
  // only on most directions; the old rule turned those into 0-width chords and picked them as the minimum.
  Poly c;
  for (int i = 0; i <= 60; ++i) c.push_back({300 + 80 * std::cos(i * M_PI / 60), 240 + 80 * std::sin(i * M_PI / 60)});
  for (int i = 60; i >= 0; --i) c.push_back({300 + 70 * std::cos(i * M_PI / 60), 240 + 70 * std::sin(i * M_PI / 60)});
  Geometry g = polygon_geometry(c, {300, 290});  // inside the arc's bowl: below it, off the material
  GripOptions o;
  Grip gr = grip_of(g, o);
  if (gr.feasible) {
    EXPECT_GT(gr.opening_px, o.min_opening_px);
    // Real contacts on both sides of the centroid.
    EXPECT_LT((gr.p1 - g.centroid).dot(gr.p2 - g.centroid), 0);
  } else {
    EXPECT_NE(gr.reason, GripReason::None);
  }
  // The arc seen from outside (centroid above it): every line through it meets the arc on one side only.
  Geometry above = polygon_geometry(c, {300, 100});
  Grip none = grip_of(above, o);
  EXPECT_FALSE(none.feasible);
  EXPECT_EQ(none.reason, GripReason::NoContact);
}

TEST(GripSafety, NoContactInsideACrackNarrowerThanAFinger) {
  // An ellipse 80 x 50 px with a crack 1 px wide and 6 px deep in its rim at the end of its short axis (coins.png's
  // round17: a dark pit in the rim cut its outline so): the narrowest line runs into the crack, 44 px. No finger
  // fits in it, so the grip is the ellipse's 50 px; a notch 6 px wide is a real way in and keeps its 44 px.
  auto ellipse_with_notch = [](double width) {
    const double A = 40, B = 25, a = std::asin(width / 2 / A);
    Poly p;
    for (int i = 0; i <= 720; ++i) {
      double t = -M_PI / 2 + a + i * (2 * M_PI - 2 * a) / 720;
      p.push_back({300 + A * std::cos(t), 240 + B * std::sin(t)});
    }
    p.push_back({300 - width / 2, 240 - B + 6});  // the notch's floor, 6 px into the rim from above
    p.push_back({300 + width / 2, 240 - B + 6});
    return p;
  };
  GripOptions o;
  Grip crack = grip_of(polygon_geometry(ellipse_with_notch(1.0), {300, 240}), o);
  EXPECT_TRUE(crack.feasible);
  EXPECT_NEAR(crack.opening_px, 50, 0.3);
  Grip notch = grip_of(polygon_geometry(ellipse_with_notch(6.0), {300, 240}), o);
  EXPECT_TRUE(notch.feasible);
  EXPECT_NEAR(notch.opening_px, 44, 0.3);
}

TEST(GripSafety, ZeroWidthIsNeverFeasible) {
  Geometry g = polygon_geometry(rectangle({300, 240}, 100, 40, 0), {300, 240});
  GripOptions o;
  o.min_opening_px = 0;  // even when the caller allows it
  Grip gr = grip_of(g, o);
  EXPECT_TRUE(gr.feasible);
  EXPECT_NEAR(gr.opening_px, 40, 1e-6);
  Geometry empty;
  empty.centroid = {10, 10};
  Grip e = grip_of(empty, o);
  EXPECT_FALSE(e.feasible);
  EXPECT_EQ(e.reason, GripReason::NoContact);
  EXPECT_EQ(e.opening_px, 0);
}

TEST(GripSafety, TooNarrowAndTooWide) {
  Geometry g = polygon_geometry(rectangle({300, 240}, 100, 4, 20), {300, 240});
  GripOptions o;
  o.min_opening_px = 5;
  o.max_opening_px = 50;  // the wire is 4 px across, 100 px along: nothing in [5, 50] except diagonals?
  Grip gr = grip_of(g, o);
  // Lines through the centre of a 100x4 bar: chords are 4/|sin a| up to 100; those in [5, 50] exist (near
  // the short axis), so the narrowest of them is taken: a diagonal grip on a wire would slip, but it is real.
  if (gr.feasible) {
    EXPECT_GE(gr.opening_px, 5);
    EXPECT_LE(gr.opening_px, 50);
  }
  o.max_opening_px = 4.5;
  Grip narrow = grip_of(g, o);
  EXPECT_FALSE(narrow.feasible);
  EXPECT_EQ(narrow.reason, GripReason::TooNarrow);
  Geometry big = polygon_geometry(ellipse({300, 240}, 90, 80, 0), {300, 240});
  o.min_opening_px = 2, o.max_opening_px = 100;
  Grip wide = grip_of(big, o);
  EXPECT_FALSE(wide.feasible);
  EXPECT_EQ(wide.reason, GripReason::TooWide);
  EXPECT_NEAR(wide.opening_px, 160, 0.5);
  EXPECT_STREQ(grip_reason_name(wide.reason), "too_wide");
  EXPECT_STREQ(grip_reason_name(narrow.reason), "too_narrow");
  EXPECT_EQ(grip_reason_name(GripReason::None), nullptr);
}

TEST(GripSafety, BoxedInDiscSaysFingerCollision) {
  std::optional<DetectedObject> disc = boxed_in_disc();
  ASSERT_TRUE(disc) << "disc not found";
  EXPECT_FALSE(disc->grip.feasible);
  EXPECT_EQ(disc->grip.reason, GripReason::FingerCollision);
}

}  // namespace
}  // namespace rbx1::vision

#include "draw.hpp"

namespace rbx1::vision {
namespace {

using namespace test;

TEST(Annotate, NumbersSitOnTheirOwnObjects) {
  // Close neighbours and a U whose centroid is off the material: every label anchor is on its own object.
  Poly u = {{200, 180}, {330, 180}, {330, 300}, {290, 300}, {290, 220}, {240, 220}, {240, 300}, {200, 300}};
  std::vector<Poly> polys = {u, rectangle({420, 240}, 140, 30, 80), rectangle({460, 240}, 140, 30, 80),
                             ellipse({120, 400}, 20, 20, 0)};
  Detection d = run(polys);
  ASSERT_EQ(d.objects.size(), 4u);
  for (const auto& o : d.objects) {
    cv::Point2d a = label_anchor(o);
    int own = 0;
    for (const Poly& p : polys) {
      std::vector<cv::Point2f> pf;
      for (auto v : p) pf.emplace_back(float(v.x), float(v.y));
      if (cv::pointPolygonTest(pf, cv::Point2f(a), false) > 0) own += cv::norm(poly_centroid(p) - o.geometry.centroid) < 2;
    }
    EXPECT_EQ(own, 1) << "object #" << o.index;
  }
}

}  // namespace
}  // namespace rbx1::vision
