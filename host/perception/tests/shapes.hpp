// shapes.hpp - test scenes drawn with OpenCV: anti-aliased shapes with exact area coverage (supersampled).
#pragma once
#include <vector>

#include <opencv2/core.hpp>

namespace rbx1::vision::test {

// A polygon in frame pixels (pixel centres at integer coordinates).
using Poly = std::vector<cv::Point2d>;

Poly rectangle(cv::Point2d c, double length, double width, double angle_deg);
Poly ellipse(cv::Point2d c, double a, double b, double angle_deg, int n = 720);
Poly l_shape(cv::Point2d c, double size, double arm, double angle_deg, bool mirror = false);
Poly triangle(cv::Point2d c, double size, double angle_deg);
Poly star(cv::Point2d c, double r_out, double r_in, int points, double angle_deg);
Poly regular(cv::Point2d c, double r, int sides, double angle_deg);

// Area centroid of a simple polygon.
cv::Point2d poly_centroid(const Poly& p);
// Exact minimum chord through pt between outermost crossings (the grip ground truth), over 0.05-degree steps.
double min_chord(const Poly& p, cv::Point2d pt);

struct Scene {
  cv::Size size{640, 480};
  double background = 200, object = 60;  // grey levels
  double noise_sigma = 0;
  double blur_sigma = 0;
  double light_gradient = 0;  // grey levels added from left to right edge
  unsigned seed = 1;
};
// Renders polygons (each filled) with 8x supersampling, then light gradient, blur and noise. 8-bit BGR.
cv::Mat render(const Scene& s, const std::vector<Poly>& polys);
// Coverage (0..1, CV_32F) of polygons, 8x supersampled: for composing shades and tones by hand.
cv::Mat coverage(const std::vector<Poly>& polys);
// A camera on a composed float grey image: 1 px of blur, then noise of noise_sigma (seeded). 8-bit grey.
cv::Mat camera(cv::Mat img, double noise_sigma, unsigned seed);

}  // namespace rbx1::vision::test
