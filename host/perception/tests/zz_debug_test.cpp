// zz_debug_test.cpp - temporary debugging aid.
#include <gtest/gtest.h>
#include <cstdio>
#include "shapes.hpp"
#include "detector.hpp"
#include "image_io.hpp"
namespace rbx1::vision {
TEST(Debug, Chords) {
  cv::Mat img = test::render({}, {test::rectangle({200, 150}, 120, 40, 30)});
  Detection det; std::string err;
  ASSERT_TRUE(detect(to_gray8(img), cv::Mat(), {}, nullptr, det, err));
  auto& o = det.objects[0];
  printf("centroid %.3f %.3f n=%zu\n", o.geometry.centroid.x, o.geometry.centroid.y, o.geometry.contour.size());
  for (size_t i = 0; i < o.chord_phi.size(); ++i) { double d = o.chord_phi[i]*180/M_PI; if (d > 110 && d < 130) printf("%.1f %.4f\n", d, o.chord_d[i]); }
  printf("grip %.3f angle %.3f\n", o.grip.opening_px, o.grip.angle_deg);
}
}
