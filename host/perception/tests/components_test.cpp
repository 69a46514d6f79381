// components_test.cpp - the streamed binary image and run labelling against OpenCV's own steps (threshold,
// 3x3 opening, connectedComponentsWithStats): the same labels, numbered the same, the same boxes and areas,
// also when the pass clears the rest of the label image itself, and two levels labelled in one pass.
#include <gtest/gtest.h>

#include <random>

#include <opencv2/imgproc.hpp>

#include "components.hpp"

namespace rbx1::vision {
namespace {

// Random blobs, lines and specks of both polarities on a noisy table: many components of every shape,
// including ones that start on odd rows and columns, touch the border or nest inside others.
void scene(int w, int h, unsigned seed, cv::Mat& gray, cv::Mat& bg) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> X(-10, w + 10), Y(-10, h + 10), R(1, 25), V(0, 255);
  bg = cv::Mat(h, w, CV_8U, cv::Scalar(128));
  cv::Mat n(h, w, CV_8U);
  cv::randu(n, 0, 24);
  bg += n;
  gray = bg.clone();
  for (int i = 0; i < 60; ++i) {
    cv::Point p(X(rng), Y(rng));
    if (i % 3 == 0) cv::circle(gray, p, R(rng), cv::Scalar(V(rng)), -1);
    else if (i % 3 == 1) cv::line(gray, p, {X(rng), Y(rng)}, cv::Scalar(V(rng)), 1 + R(rng) % 3);
    else cv::rectangle(gray, cv::Rect(p.x, p.y, R(rng), R(rng)), cv::Scalar(V(rng)), -1);
  }
  cv::randu(n, 0, 40);
  cv::subtract(gray, n, gray);
}

void expect_same_as_opencv(const cv::Mat& gray, const cv::Mat& bg, int s, int low, int high) {
  cv::Mat c, bin, hi, lab, st, cen;
  if (s > 0) cv::subtract(gray, bg, c);
  else cv::subtract(bg, gray, c);
  cv::threshold(c, bin, low, 255, cv::THRESH_BINARY);
  cv::morphologyEx(bin, bin, cv::MORPH_OPEN, cv::Mat());
  cv::threshold(c, hi, high, 255, cv::THRESH_BINARY);
  cv::morphologyEx(hi, hi, cv::MORPH_OPEN, cv::Mat());
  const int n = cv::connectedComponentsWithStats(bin, lab, st, cen, 8, CV_32S);
  const int on = cv::countNonZero(hi);

  cv::Mat labels(gray.size(), CV_32S, cv::Scalar(0));
  std::vector<Component> comps;
  const long long got = label_components(gray, bg, s, low, high, 7, labels, comps);
  ASSERT_EQ(got, on);
  if (on == 0) {
    EXPECT_TRUE(comps.empty());
    EXPECT_EQ(cv::countNonZero(labels), 0);
    cv::Mat dirty(gray.size(), CV_32S, cv::Scalar(-5));
    EXPECT_EQ(label_components(gray, bg, s, low, high, 7, dirty, comps, true), 0);
    EXPECT_EQ(cv::countNonZero(dirty), 0) << "clear left pixels set";
    return;
  }
  ASSERT_EQ(int(comps.size()), n - 1);
  cv::Mat expected = lab + 6;
  expected.setTo(0, lab == 0);
  EXPECT_EQ(cv::countNonZero(expected != labels), 0) << "labels differ from OpenCV's";
  // clear: the same labels written over a frame of garbage, every other pixel zeroed.
  cv::Mat dirty(gray.size(), CV_32S, cv::Scalar(-5));
  std::vector<Component> comps2;
  ASSERT_EQ(label_components(gray, bg, s, low, high, 7, dirty, comps2, true), on);
  EXPECT_EQ(cv::countNonZero(expected != dirty), 0) << "labels with clear differ from OpenCV's";
  EXPECT_EQ(comps2.size(), comps.size());
  for (int i = 1; i < n; ++i) {
    const Component& k = comps[size_t(i - 1)];
    EXPECT_EQ(k.area, st.at<int>(i, cv::CC_STAT_AREA)) << i;
    EXPECT_EQ(k.box, cv::Rect(st.at<int>(i, cv::CC_STAT_LEFT), st.at<int>(i, cv::CC_STAT_TOP),
                              st.at<int>(i, cv::CC_STAT_WIDTH), st.at<int>(i, cv::CC_STAT_HEIGHT)))
        << i;
    EXPECT_EQ(k.strong, cv::countNonZero(hi & (lab == i)) > 0) << i;
  }
}

TEST(Components, SameAsOpenCVThresholdOpeningAndLabels) {
  for (unsigned seed = 1; seed <= 12; ++seed) {
    // Widths that are not multiples of 8 or 16, odd heights, a single row and column.
    const int w = seed == 11 ? 1 : 37 + 53 * int(seed), h = seed == 12 ? 1 : 29 + 31 * int(seed);
    cv::Mat gray, bg;
    scene(w, h, seed, gray, bg);
    for (int s : {-1, +1})
      for (auto [low, high] : {std::pair{6, 12}, {20, 45}, {0, 0}, {60, 254}})
        expect_same_as_opencv(gray, bg, s, low, high);
  }
}

// Two labellings in one pass (the grey shade's and the isolation's dark polarity) are each the single pass's:
// the same labels, components and counts, one written into a kept-zero image, the other clearing garbage.
TEST(Components, TwoLevelsInOnePassEqualTwoPasses) {
  for (unsigned seed = 1; seed <= 6; ++seed) {
    const int w = 41 + 57 * int(seed), h = 23 + 29 * int(seed);
    cv::Mat gray, bg;
    scene(w, h, seed, gray, bg);
    for (int s : {-1, +1})
      for (auto [a, b] : {std::pair{std::pair{3, 3}, std::pair{6, 12}}, {{20, 45}, {0, 0}}, {{6, 12}, {250, 254}}}) {
        cv::Mat one_a(gray.size(), CV_32S, cv::Scalar(0)), one_b(gray.size(), CV_32S, cv::Scalar(0));
        std::vector<Component> ca, cb;
        const long long ha = label_components(gray, bg, s, a.first, a.second, 1, one_a, ca);
        const long long hb = label_components(gray, bg, s, b.first, b.second, 3, one_b, cb, true);
        cv::Mat two_a(gray.size(), CV_32S, cv::Scalar(0)), two_b(gray.size(), CV_32S, cv::Scalar(-5));
        std::vector<Component> da, db;
        Labelling both[2] = {{a.first, a.second, 1, &two_a, &da, false}, {b.first, b.second, 3, &two_b, &db, true}};
        label_components(gray, bg, s, both, 2);
        EXPECT_EQ(both[0].above_high, ha);
        EXPECT_EQ(both[1].above_high, hb);
        EXPECT_EQ(cv::countNonZero(one_a != two_a), 0) << seed << " " << s;
        EXPECT_EQ(cv::countNonZero(one_b != two_b), 0) << seed << " " << s;
        ASSERT_EQ(da.size(), ca.size());
        ASSERT_EQ(db.size(), cb.size());
        for (size_t i = 0; i < ca.size(); ++i)
          EXPECT_TRUE(da[i].area == ca[i].area && da[i].box == ca[i].box && da[i].strong == ca[i].strong) << i;
        for (size_t i = 0; i < cb.size(); ++i)
          EXPECT_TRUE(db[i].area == cb[i].area && db[i].box == cb[i].box && db[i].strong == cb[i].strong) << i;
      }
  }
}

TEST(Components, NothingAboveHighAddsNothing) {
  cv::Mat bg(40, 50, CV_8U, cv::Scalar(100)), gray = bg.clone();
  cv::rectangle(gray, cv::Rect(10, 10, 12, 12), cv::Scalar(80), -1);  // contrast 20: above 10, not above 30
  cv::Mat labels(bg.size(), CV_32S, cv::Scalar(0));
  std::vector<Component> comps;
  EXPECT_EQ(label_components(gray, bg, -1, 10, 30, 1, labels, comps), 0);
  EXPECT_TRUE(comps.empty());
  EXPECT_EQ(cv::countNonZero(labels), 0);
  EXPECT_EQ(label_components(gray, bg, -1, 10, 15, 1, labels, comps), 144);
  ASSERT_EQ(comps.size(), 1u);
  EXPECT_EQ(comps[0].box, cv::Rect(10, 10, 12, 12));
  EXPECT_EQ(cv::countNonZero(labels == 1), 144);
}

}  // namespace
}  // namespace rbx1::vision
