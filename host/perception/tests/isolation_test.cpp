// isolation_test.cpp - step I: both polarities, known background, patterned and unevenly lit tables, specks,
// border objects, wrong background size and all-foreground frames.
#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/imgproc.hpp>

#include "detector.hpp"
#include "image_io.hpp"
#include "isolate.hpp"
#include "shapes.hpp"

namespace rbx1::vision {
namespace {

using namespace test;

std::vector<Poly> three() {
  return {rectangle({150, 120}, 100, 40, 20), ellipse({450, 150}, 50, 30, -30), triangle({300, 350}, 90, 10)};
}

int count(const cv::Mat& bgr, Polarity p, const cv::Mat& bg = {}) {
  DetectorOptions o;
  o.objects = p;
  Detection d;
  std::string e;
  EXPECT_TRUE(detect(to_gray8(bgr), bg.empty() ? bg : to_gray8(bg), o, nullptr, d, e)) << e;
  return int(d.objects.size());
}

TEST(Isolation, DarkObjectsOnLightTable) {
  Scene s;
  s.noise_sigma = 4;
  cv::Mat img = render(s, three());
  EXPECT_EQ(count(img, Polarity::Auto), 3);
  EXPECT_EQ(count(img, Polarity::Dark), 3);
}

TEST(Isolation, LightObjectsOnDarkTable) {
  Scene s;
  s.background = 40, s.object = 200, s.noise_sigma = 4;
  cv::Mat img = render(s, three());
  EXPECT_EQ(count(img, Polarity::Auto), 3);
  EXPECT_EQ(count(img, Polarity::Light), 3);
  Detection d;
  std::string e;
  ASSERT_TRUE(detect(to_gray8(img), {}, {}, nullptr, d, e));
  ASSERT_EQ(d.objects.size(), 3u);
  for (const auto& o : d.objects) EXPECT_EQ(o.layer.sign, +1);
}

TEST(Isolation, UnevenLightAndBlur) {
  Scene s;
  s.light_gradient = 60, s.blur_sigma = 1.2, s.noise_sigma = 3;
  EXPECT_EQ(count(render(s, three()), Polarity::Auto), 3);
}

// A table with a fine pattern (a wood-grain-like texture of thin stripes), with and without a known background.
cv::Mat patterned(const cv::Mat& scene, const std::vector<Poly>& polys) {
  cv::Mat pattern(scene.size(), CV_8UC3);
  for (int y = 0; y < scene.rows; ++y)
    for (int x = 0; x < scene.cols; ++x)
      pattern.at<cv::Vec3b>(y, x) = cv::Vec3b::all(uchar(185 + 14 * std::sin(x * 0.9 + 0.3 * y)));
  cv::Mat mask(scene.size(), CV_8U, cv::Scalar(0));
  for (const Poly& p : polys) {
    std::vector<cv::Point> q;
    for (auto v : p) q.emplace_back(int(std::lround(v.x)), int(std::lround(v.y)));
    cv::fillPoly(mask, std::vector<std::vector<cv::Point>>{q}, cv::Scalar(255));
  }
  cv::Mat out = pattern.clone();
  scene.copyTo(out, mask);
  return out;
}

TEST(Isolation, PatternedTableAutomaticAndKnownBackground) {
  Scene s;
  s.object = 50;
  cv::Mat plain = render(s, three());
  cv::Mat img = patterned(plain, three());
  cv::Mat empty = patterned(render(s, {}), {});
  EXPECT_EQ(count(img, Polarity::Auto), 3);
  EXPECT_EQ(count(img, Polarity::Auto, empty), 3);
  EXPECT_EQ(count(empty, Polarity::Auto), 0);  // no phantom objects on the empty patterned table
}

TEST(Isolation, KnownBackgroundSubtraction) {
  Scene s;
  s.light_gradient = 80;  // strong vignetting: the empty-scene image removes it exactly
  s.noise_sigma = 2;
  cv::Mat bg = render(s, {});
  s.seed = 9;
  cv::Mat img = render(s, three());
  EXPECT_EQ(count(img, Polarity::Dark, bg), 3);
}

TEST(Isolation, BackgroundOfAnotherSizeIsAnError) {
  Detection d;
  std::string e;
  cv::Mat img = to_gray8(render({}, three()));
  EXPECT_FALSE(detect(img, cv::Mat(100, 100, CV_8U, cv::Scalar(200)), {}, nullptr, d, e));
  EXPECT_NE(e.find("background is 100x100 but the frame is 640x480"), std::string::npos) << e;
}

TEST(Isolation, AllForegroundIsAnError) {
  Detection d;
  std::string e;
  cv::Mat img(480, 640, CV_8U, cv::Scalar(30)), bg(480, 640, CV_8U, cv::Scalar(220));
  EXPECT_FALSE(detect(img, bg, {}, nullptr, d, e));
  EXPECT_NE(e.find("foreground"), std::string::npos) << e;
}

TEST(Isolation, SpecksAndBorderObjectsAreDropped) {
  Scene s;
  s.noise_sigma = 3;
  std::vector<Poly> polys = three();
  polys.push_back(rectangle({322, 60}, 4, 4, 0));     // a speck
  polys.push_back(rectangle({10, 300}, 60, 30, 0));   // cut by the left border
  Detection d;
  std::string e;
  ASSERT_TRUE(detect(to_gray8(render(s, polys)), {}, {}, nullptr, d, e));
  EXPECT_EQ(d.objects.size(), 3u);
  EXPECT_EQ(d.isolation.border, 1);
  EXPECT_GE(d.isolation.specks, 1);
}

TEST(Isolation, NoPhantomsOnEmptyNoisyScenes) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    Scene s;
    s.noise_sigma = 8, s.light_gradient = 40, s.blur_sigma = 0.5, s.seed = seed;
    EXPECT_EQ(count(render(s, {}), Polarity::Auto), 0) << "seed " << seed;
  }
}

TEST(Isolation, SoftShadowDoesNotPullTheCentroid) {
  // A soft shadow (35 grey levels, offset 7 px) joined to a dark bar: above the noise threshold, below half
  // the bar's contrast.
  Poly bar = rectangle({320, 240}, 140, 50, 20);
  Poly shadow = rectangle({327, 247}, 140, 50, 20);
  Scene sh;
  sh.object = 165, sh.blur_sigma = 4;
  cv::Mat base = to_gray8(render(sh, {shadow}));
  Scene cov;
  cov.background = 0, cov.object = 255;
  cv::Mat f = to_gray8(render(cov, {bar}));
  cv::Mat img(base.size(), CV_8U);
  cv::RNG rng(5);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      double a = f.at<uchar>(y, x) / 255.0;
      img.at<uchar>(y, x) = cv::saturate_cast<uchar>(base.at<uchar>(y, x) * (1 - a) + 60 * a + rng.gaussian(3));
    }
  Detection d;
  std::string e;
  ASSERT_TRUE(detect(img, {}, {}, nullptr, d, e)) << e;
  ASSERT_EQ(d.objects.size(), 1u);
  cv::Point2d truth = poly_centroid(bar);
  EXPECT_LT(cv::norm(d.objects[0].geometry.centroid - truth), 0.3) << d.objects[0].geometry.centroid;
  EXPECT_NEAR(d.objects[0].grip.opening_px, 50, 1.0);
}

TEST(Isolation, LightObjectsDarkShadowIsNotTheObject) {
  // A light part (210) on a dark table (55) with its background, its strong cast shadow (40 % darker, offset
  // 7 px right and down) along one long side and one end: the shadow wraps over 40 % of the part's outline. The
  // shadow, a dark region far fainter than the part, is the part's fringe; the part is not a detail of it.
  Poly bar = rectangle({320, 240}, 120, 40, 0);
  Scene cov;
  cov.background = 0, cov.object = 255;
  cv::Mat a8 = to_gray8(render(cov, {bar})), alpha, shade;
  a8.convertTo(alpha, CV_32F, 1.0 / 255);
  cv::warpAffine(alpha, shade, cv::Mat_<double>({2, 3}, {1, 0, 7, 0, 1, 7}), alpha.size());
  cv::GaussianBlur(shade, shade, cv::Size(), 2.0);
  cv::Mat img = 55.0 * (1.0 - 0.4 * shade);
  img = img.mul(1.0 - alpha) + 210.0 * alpha;
  cv::Mat noise(img.size(), CV_32F), frame, bg;
  cv::RNG(9).fill(noise, cv::RNG::NORMAL, 0, 2.0);
  cv::Mat(img + noise).convertTo(frame, CV_8U);
  cv::RNG(10).fill(noise, cv::RNG::NORMAL, 0, 2.0);
  cv::Mat(cv::Mat(img.size(), CV_32F, cv::Scalar(55)) + noise).convertTo(bg, CV_8U);
  Detection d;
  std::string e;
  ASSERT_TRUE(detect(frame, bg, {}, nullptr, d, e)) << e;
  ASSERT_EQ(d.objects.size(), 1u);
  EXPECT_LT(cv::norm(d.objects[0].geometry.centroid - poly_centroid(bar)), 0.3);
  EXPECT_NEAR(d.objects[0].grip.opening_px, 40, 1.0);
  EXPECT_GE(d.isolation.fringes, 1);
}

TEST(Isolation, TexturedObjectOnATexturedTableIsOneObject) {
  // A worn coin on a cloth (data/corpus/coins.png came out in 32 pieces for 24 coins): stripes of its relief
  // are only 28 levels above the table, whose texture (sigma 8) puts the threshold at 36. Regions grown down
  // to half the threshold from the bright stripes keep the coin whole.
  Scene s;
  s.background = 100, s.object = 160, s.blur_sigma = 0.7;
  const cv::Point2d c(320, 240);
  cv::Mat img = render(s, {ellipse(c, 40, 40, 0)}), noise(img.size(), CV_32FC3);
  img.convertTo(img, CV_32FC3);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      if (std::hypot(x - c.x, y - c.y) < 38 && (x / 6) % 2) img.at<cv::Vec3f>(y, x) -= cv::Vec3f(32, 32, 32);
  cv::setRNGSeed(7);
  cv::randn(noise, 0, 8);
  img += noise;
  img.convertTo(img, CV_8UC3);
  DetectorOptions o;
  Detection d;
  std::string e;
  ASSERT_TRUE(detect(to_gray8(img), {}, o, nullptr, d, e)) << e;
  ASSERT_EQ(d.objects.size(), 1u);
  EXPECT_LT(cv::norm(d.objects[0].geometry.centroid - c), 1.5);
  EXPECT_NEAR(d.objects[0].grip.opening_px, 80, 4);
}

TEST(Isolation, ShadeBetweenTwoObjectsIsNoObject) {
  // Two dark sweets 10 px apart on a white table with the shade between them (data/corpus/smarties.png): the
  // shade joins them at the low threshold and stays above the region's half level, but it is far fainter
  // and smaller than either sweet: their shadow, not a third object.
  Scene s;
  s.background = 230, s.object = 80, s.blur_sigma = 0.8;
  cv::Mat sweets = render(s, {ellipse({300, 240}, 25, 25, 0), ellipse({360, 240}, 25, 25, 0)});
  s.object = 130;
  cv::Mat shade = render(s, {ellipse({330, 240}, 5, 12, 0)}), img = cv::min(sweets, shade), noise(img.size(), CV_16SC3);
  cv::setRNGSeed(3);
  cv::randn(noise, 0, 2);
  img.convertTo(img, CV_16SC3);
  img += noise;
  img.convertTo(img, CV_8UC3);
  EXPECT_EQ(count(img, Polarity::Auto), 2);
  EXPECT_EQ(count(img, Polarity::Dark), 2);
}

TEST(Isolation, NearObjectsStaySeparate) {
  Scene s;
  s.noise_sigma = 3, s.blur_sigma = 0.8;
  // Two bars 3 px apart.
  EXPECT_EQ(count(render(s, {rectangle({250, 240}, 120, 40, 0), rectangle({250, 283}, 120, 40, 0)}), Polarity::Auto), 2);
}

// The automatic background's global surface (one smooth level over the whole table) lies above a darker patch
// of cloth around a light disc, whose faint relief on one side (a segment beyond 0.6 of its radius) is then
// below the low threshold against the surface but well above the patch: the outline keeps the whole disc, as
// the patch's own level beside it has it, not a disc with that side cut off (14 % of its area).
TEST(Isolation, LocalTableLevelBesideAnObjectKeepsItsFaintRelief) {
  cv::Mat gray(300, 400, CV_8U, cv::Scalar(60));
  cv::circle(gray, {200, 150}, 80, cv::Scalar(36), cv::FILLED);  // the darker patch: 24 below the surface
  const cv::Point c(200, 150);
  const int r = 30;
  for (int y = c.y - r; y <= c.y + r; ++y)
    for (int x = c.x - r; x <= c.x + r; ++x)
      if ((x - c.x) * (x - c.x) + (y - c.y) * (y - c.y) <= r * r)
        gray.at<uchar>(y, x) = x > c.x + 0.6 * r ? 64 : 86;  // relief 28 above the patch, body 50
  const int disc = cv::countNonZero(gray == 86) + cv::countNonZero(gray == 64);
  Contrast con;
  con.gray = gray;
  con.background = cv::Mat(gray.size(), CV_8U, cv::Scalar(60));
  con.sign = +1, con.noise_sigma = 2, con.global_model = true, con.modelled = true;
  IsolationOptions opt;
  Isolation iso;
  std::string e;
  ASSERT_TRUE(isolate(con, opt, iso, e)) << e;
  ASSERT_EQ(iso.layers.size(), 1u);
  const Layer& l = iso.layers[0];
  EXPECT_EQ(l.sign, +1);
  const int inside = cv::countNonZero(l.inside);
  EXPECT_GE(inside, disc * 97 / 100) << "of " << disc;
  EXPECT_LE(inside, disc);
  const cv::Rect box = cv::boundingRect(l.inside) + l.roi.tl();
  EXPECT_EQ(box, cv::Rect(c.x - r, c.y - r, 2 * r + 1, 2 * r + 1));
}

// The label frame is kept between frames and only the boxes written into it are cleared (label_frame): a frame
// labelled after another one's detection is released gives the same labels and objects as a new, zeroed frame
// (made while the first result is still held), with a known background and without, both polarities.
TEST(Isolation, AKeptLabelFrameIsClearedLikeANewOne) {
  Scene s;
  s.noise_sigma = 3;
  const cv::Mat empty = to_gray8(render(s, {}));
  cv::Mat a = to_gray8(render(s, {rectangle({120, 100}, 150, 40, 30), ellipse({500, 380}, 70, 40, 10),
                                  triangle({330, 240}, 120, 5), star({520, 110}, 60, 25, 5, 0)}));
  cv::Mat b = to_gray8(render(s, {ellipse({200, 330}, 60, 30, -20), rectangle({420, 150}, 120, 30, 70)}));
  cv::rectangle(b, cv::Rect(60, 60, 50, 30), cv::Scalar(250), cv::FILLED);  // a light object too
  for (const cv::Mat& bg : {empty, cv::Mat()}) {
    std::string e;
    Detection first;
    ASSERT_TRUE(detect(a, bg, {}, nullptr, first, e)) << e;
    ASSERT_GE(first.objects.size(), 3u);
    first = Detection{};  // released: the next frame reuses its label frame
    Detection reused, fresh;
    ASSERT_TRUE(detect(b, bg, {}, nullptr, reused, e)) << e;
    ASSERT_TRUE(detect(b, bg, {}, nullptr, fresh, e)) << e;  // `reused` still holds the kept frame
    ASSERT_NE(reused.isolation.labels.data, fresh.isolation.labels.data);
    EXPECT_EQ(cv::countNonZero(reused.isolation.labels != fresh.isolation.labels), 0);
    ASSERT_EQ(reused.objects.size(), fresh.objects.size());
    EXPECT_EQ(reused.objects.size(), 3u);
    for (size_t i = 0; i < fresh.objects.size(); ++i) {
      EXPECT_EQ(reused.objects[i].geometry.centroid, fresh.objects[i].geometry.centroid) << i;
      EXPECT_EQ(reused.objects[i].grip.opening_px, fresh.objects[i].grip.opening_px) << i;
    }
  }
}

}  // namespace
}  // namespace rbx1::vision
