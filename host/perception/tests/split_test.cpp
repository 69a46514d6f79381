// split_test.cpp - touching objects are cut apart at their necks, each with its own grip clear of the other;
// single objects with no neck (bars, L shapes, stars, discs) stay whole.
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>

#include "detector.hpp"
#include "image_io.hpp"
#include "shapes.hpp"

namespace rbx1::vision {
namespace {

using namespace test;

Detection run(const std::vector<Poly>& polys, double finger = 0) {
  Scene s;
  s.noise_sigma = 2, s.blur_sigma = 0.7;
  DetectorOptions o;
  o.grip.finger_width_px = finger, o.grip.finger_depth_px = finger;
  Detection d;
  std::string e;
  EXPECT_TRUE(detect(to_gray8(render(s, polys)), {}, o, nullptr, d, e)) << e;
  return d;
}

const DetectedObject* near(const Detection& d, cv::Point2d c, double tol) {
  for (const auto& o : d.objects)
    if (cv::norm(o.geometry.centroid - c) < tol) return &o;
  return nullptr;
}

TEST(Split, TwoTouchingDiscsBecomeTwoObjects) {
  Poly a = ellipse({250, 240}, 45, 45, 0), b = ellipse({338, 240}, 45, 45, 0);  // 2 px overlap
  Detection d = run({a, b});
  ASSERT_EQ(d.objects.size(), 2u);
  for (const auto* c : {near(d, {250, 240}, 3), near(d, {338, 240}, 3)}) {
    ASSERT_TRUE(c);
    EXPECT_TRUE(c->touching);
    EXPECT_NEAR(c->geometry.area_px, M_PI * 45 * 45, 0.05 * M_PI * 45 * 45);
    EXPECT_TRUE(c->grip.feasible);
    // Not at the junction: both contacts at least a (default 3 px) finger away from the other disc.
    cv::Point2d other = c->geometry.centroid.x < 294 ? cv::Point2d(338, 240) : cv::Point2d(250, 240);
    for (cv::Point2d p : {c->grip.p1, c->grip.p2}) EXPECT_GT(cv::norm(p - other) - 45, 3.0);
    EXPECT_GT(std::abs(c->grip.angle_deg), 15);
  }
}

TEST(Split, BarTouchingADiscEachGrippedClearOfTheOther) {
  // The disc rests against the bar's long side: a neck far narrower than either body.
  Poly bar = rectangle({220, 230}, 160, 60, 0), disc = ellipse({220, 300}, 40, 40, 0);
  Detection d = run({bar, disc}, 10);
  ASSERT_EQ(d.objects.size(), 2u);
  const DetectedObject* b = near(d, {220, 230}, 4);
  ASSERT_TRUE(b);
  EXPECT_TRUE(b->touching);
  EXPECT_NEAR(std::abs(b->pose.orientation_deg), 0, 2);
  EXPECT_TRUE(b->grip.feasible);
  // Every closing line passes through the centroid, right above the contact: the straight grip across (60 px)
  // would put a finger on the disc, so a slanted, wider chord is taken, its lower finger clear of the disc.
  EXPECT_GT(b->grip.opening_px, 65);
  for (cv::Point2d p : {b->grip.p1, b->grip.p2}) EXPECT_GT(cv::norm(p - cv::Point2d(220, 300)) - 40, 3.0);
}

TEST(Split, SingleObjectsStayWhole) {
  Detection d = run({rectangle({150, 120}, 200, 40, 15), l_shape({450, 130}, 120, 35, 20), star({160, 340}, 70, 35, 5, 0),
                     ellipse({450, 350}, 70, 70, 0), triangle({300, 250}, 60, 0)});
  EXPECT_EQ(d.objects.size(), 5u);
  for (const auto& o : d.objects) EXPECT_FALSE(o.touching);
}

TEST(Split, NarrowPartsStayWithTheirBody) {
  // Issue 27: a fruit's leaf on its stem, a crown's ball-tipped prongs, a pan's grip at the end of its handle
  // and a dumbbell (two discs on a long bar) were cut off as touching objects. Each is one object; beside them
  // two discs touching are still two.
  std::vector<Poly> polys = {ellipse({110, 130}, 40, 40, 0), rectangle({112, 80}, 22, 5, 80),  // fruit, stem
                             ellipse({128, 64}, 20, 8, -15)};                                 // leaf
  polys.push_back(rectangle({320, 140}, 120, 36, 0));                                         // crown's band
  for (int k = 0; k < 5; ++k) {
    const double x = 270 + 25 * k, top = 122 - 26 - 6 * (2 - std::abs(k - 2));
    polys.push_back(rectangle({x, (top + 124) / 2}, 124 - top, 6, 90));                      // prong
    polys.push_back(ellipse({x, top - 4}, 8, 8, 0));                                          // ball
  }
  polys.push_back(ellipse({500, 130}, 38, 38, 0));                                            // pan
  polys.push_back(rectangle({563, 130}, 50, 9, 0));                                           // handle
  polys.push_back(ellipse({603, 130}, 22, 10, 0));                                            // grip
  polys.push_back(ellipse({110, 350}, 30, 30, 0));                                            // dumbbell
  polys.push_back(ellipse({250, 350}, 30, 30, 0));
  polys.push_back(rectangle({180, 350}, 90, 10, 0));
  polys.push_back(ellipse({420, 350}, 40, 40, 0));                                            // two discs
  polys.push_back(ellipse({503, 350}, 44, 44, 0));
  Detection d = run(polys);
  ASSERT_EQ(d.objects.size(), 6u);
  int touching = 0;
  for (const auto& o : d.objects) touching += o.touching;
  EXPECT_EQ(touching, 2);
  for (cv::Point2d c : {cv::Point2d(112, 122), cv::Point2d(320, 125), cv::Point2d(525, 130), cv::Point2d(180, 350)}) {
    const DetectedObject* o = near(d, c, 15);
    ASSERT_TRUE(o) << c;
    EXPECT_FALSE(o->touching) << c;
  }
}

TEST(Split, PersistenceRejectsShallowWaists) {
  // Two overlapping discs (r = 40) drawn as one region: a waist of 85 % of their width is one object (an
  // oval with a slight dent), a waist of 40 % is two objects touching.
  auto waist_pair = [](cv::Point2d c, double ratio) {
    double half = 40 * std::sqrt(1 - ratio * ratio);  // centre offset for a neck of ratio * 80 px
    return std::vector<Poly>{ellipse({c.x - half, c.y}, 40, 40, 0), ellipse({c.x + half, c.y}, 40, 40, 0)};
  };
  std::vector<Poly> polys = waist_pair({160, 240}, 0.85);
  for (const Poly& p : waist_pair({460, 240}, 0.4)) polys.push_back(p);
  Detection d = run(polys);
  int left = 0, right = 0;
  for (const auto& o : d.objects) (o.geometry.centroid.x < 310 ? left : right)++;
  EXPECT_EQ(left, 1);
  EXPECT_EQ(right, 2);
}

TEST(Split, AWaistFlushWithOneSideIsNotAContact) {
  // stuff.jpg's lighter in outline: a head (48 x 16 px) joined to its body (48 x 100 px) by a 6 px strip
  // along the right side only (the band under the head is at the table's level). The strip is a neck under
  // half the head's height, so persistence alone cut the head off; the cut's right end is on the straight
  // side (no concavity there), so it is one object.
  const double x = 300, y = 150;
  Poly lighter = {{x, y}, {x + 48, y}, {x + 48, y + 130}, {x, y + 130}, {x, y + 30}, {x + 42, y + 30}, {x + 42, y + 16},
                  {x, y + 16}};
  // Beside it, two bars touching corner to side: both ends of that cut are in concavities.
  Detection d = run({lighter, rectangle({120, 200}, 120, 30, 0), rectangle({150, 274}, 120, 30, 60)});
  const DetectedObject* l = near(d, {x + 24.3, y + 69.5}, 6);
  ASSERT_TRUE(l);
  EXPECT_FALSE(l->touching);
  EXPECT_NEAR(l->geometry.area_px, 48 * 130 - 42 * 14, 150);
  EXPECT_NEAR(std::abs(l->pose.orientation_deg), 90, 3);
  int touching = 0;
  for (const auto& o : d.objects) touching += o.touching;
  EXPECT_EQ(d.objects.size(), 3u);
  EXPECT_EQ(touching, 2);
}

TEST(Split, ACrowdCutByTheFrameKeepsItsWholeBodies) {
  // Three rows of four discs, each touching its neighbours (2 px overlap), the left column cut by the frame's
  // left edge (water_coins.jpg: 24 coins in one region reaching two edges): the crowd is split, the cut discs
  // are dropped (as one body or more), the nine whole ones are objects, each touching.
  std::vector<Poly> polys;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) polys.push_back(ellipse({10.0 + 58 * c, 140.0 + 58 * r}, 30, 30, 0));
  Detection d = run(polys);
  EXPECT_GE(d.isolation.border, 1);
  ASSERT_EQ(d.objects.size(), 9u);
  for (int r = 0; r < 3; ++r)
    for (int c = 1; c < 4; ++c) {
      const DetectedObject* o = near(d, {10.0 + 58 * c, 140.0 + 58 * r}, 2);
      ASSERT_TRUE(o) << c << "," << r;
      EXPECT_TRUE(o->touching);
      EXPECT_NEAR(o->geometry.area_px, M_PI * 30 * 30, 0.06 * M_PI * 30 * 30);
    }
}

TEST(Split, ADarkDiscInFrontOfALighterOneKeepsItsWholeOutline) {
  // smarties.png's pair: a dark sweet (contrast 170) lying in front of a lighter one (contrast 80), their
  // centres 1.8 radii apart. The neck's watershed is a straight cut half-way between the centres, 4.5 px
  // inside the dark disc's arc; the cut between bodies of such different levels follows the contrast instead,
  // so the dark disc keeps its whole outline and the lighter one only what shows of it.
  const double r = 45;
  const cv::Point2d ca(250, 240), cb(331, 240);
  Scene cover_scene;
  cover_scene.background = 0, cover_scene.object = 255;
  cv::Mat a8, b8, a, b;
  cv::extractChannel(render(cover_scene, {ellipse(ca, r, r, 0)}), a8, 0);
  cv::extractChannel(render(cover_scene, {ellipse(cb, r, r, 0)}), b8, 0);
  a8.convertTo(a, CV_32F, 1.0 / 255);
  b8.convertTo(b, CV_32F, 1.0 / 255);
  cv::Mat img = 200 + (120 - 200) * a;  // the lighter disc on the table
  img += (30 - img).mul(b);              // the dark one in front of it
  cv::GaussianBlur(img, img, cv::Size(), 0.7);
  cv::Mat noise(img.size(), CV_32F);
  cv::RNG rng(1);
  rng.fill(noise, cv::RNG::NORMAL, 0, 2);
  img += noise;
  cv::Mat gray;
  img.convertTo(gray, CV_8U);
  cv::Mat shown = a.mul(1 - b);  // what shows of the lighter disc
  const cv::Moments m = cv::moments(shown);
  const cv::Point2d ca_shown(m.m10 / m.m00, m.m01 / m.m00);
  Detection d;
  std::string e;
  ASSERT_TRUE(detect(gray, {}, DetectorOptions{}, nullptr, d, e)) << e;
  ASSERT_EQ(d.objects.size(), 2u);
  const DetectedObject* dark = near(d, cb, 3);
  const DetectedObject* light = near(d, ca_shown, 3);
  ASSERT_TRUE(dark);
  ASSERT_TRUE(light);
  EXPECT_TRUE(dark->touching);
  EXPECT_NEAR(dark->geometry.area_px, M_PI * r * r, 0.01 * M_PI * r * r);
  EXPECT_LT(cv::norm(dark->geometry.centroid - cb), 0.3);
  // (Its edge pixels along the cut count whole: +1.5 %.)
  EXPECT_NEAR(light->geometry.area_px, m.m00, 0.02 * m.m00);
  EXPECT_LT(cv::norm(light->geometry.centroid - ca_shown), 0.5);
}

}  // namespace
}  // namespace rbx1::vision
