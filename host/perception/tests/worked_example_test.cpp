// worked_example_test.cpp - the paper's Section 4: about 918 edge points centred at (157, 145) at 40 degrees,
// axis y = 0.84 x + 13.26, minimum D at pi/2 from the axis.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "detector.hpp"
#include "image_io.hpp"
#include "pose.hpp"
#include "shapes.hpp"

namespace rbx1::vision {
namespace {

using namespace test;

TEST(WorkedExample, ReproducesSection4) {
  // An elongated object like Fig. 14 (an ellipse of axes 126 x 48 px) on a 320 x 290 frame.
  Scene s;
  s.size = {320, 290};
  s.blur_sigma = 0.7;
  s.noise_sigma = 2;
  cv::Mat img = render(s, {ellipse({157, 145}, 63, 24, 40)});
  Detection det;
  std::string error;
  ASSERT_TRUE(detect(to_gray8(img), cv::Mat(), {}, nullptr, det, error)) << error;
  ASSERT_EQ(det.objects.size(), 1u);
  const DetectedObject& o = det.objects[0];
  std::printf("n = %d, centre (%.3f, %.3f), orientation %.3f deg, axis y = %.4f x + %.3f, grip at %.2f deg from the axis\n",
              o.geometry.edge_pixels, o.geometry.centroid.x, o.geometry.centroid.y, o.pose.orientation_deg,
              o.pose.slope.value_or(0), o.pose.intercept.value_or(0),
              fold_axis_deg(o.grip.angle_deg - o.pose.orientation_deg));
  // 1- the number of edge points: about 918 (within 5%).
  EXPECT_NEAR(o.geometry.edge_pixels, 918, 46);
  // 2- the centre point (157, 145).
  EXPECT_NEAR(o.geometry.centroid.x, 157, 0.1);
  EXPECT_NEAR(o.geometry.centroid.y, 145, 0.1);
  // 3- the orientation: 40 degrees.
  EXPECT_NEAR(o.pose.orientation_deg, 40, 0.2);
  EXPECT_TRUE(o.pose.elongated);
  // 4- the axis line y = 0.84 x + 13.26 (the paper rounds the slope to two places: tan 40 = 0.8391).
  ASSERT_TRUE(o.pose.slope && o.pose.intercept);
  EXPECT_NEAR(*o.pose.slope, 0.84, 0.005);
  EXPECT_NEAR(*o.pose.intercept, 13.26, 0.8);
  // The minimum of D lies pi/2 from the axis: the fingers close across the object, along -50 degrees.
  EXPECT_NEAR(std::abs(fold_axis_deg(o.grip.angle_deg - o.pose.orientation_deg)), 90, 1.0);
  EXPECT_NEAR(o.grip.opening_px, 48, 0.5);
  // And D(theta) of Fig. 18: largest along the axis (the length, 126 px), smallest across it.
  double dmax = 0;
  for (double d : o.chord_d) dmax = std::max(dmax, d);
  EXPECT_NEAR(dmax, 126, 1.0);
}

}  // namespace
}  // namespace rbx1::vision
