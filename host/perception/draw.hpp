// draw.hpp - pictures of the results: the annotated frame (paper Fig. 20) and profile plots (Figs. 12, 13, 17, 18).
#pragma once
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "detector.hpp"

namespace rbx1::vision {

// Where the object's number is drawn: a point on the object itself (half-way along its axis when that is
// inside it, else its deepest pixel).
cv::Point2d label_anchor(const DetectedObject& o);
// The frame with each object's contour, number, principal axis, grip points and opening.
cv::Mat annotate(const cv::Mat& frame, const Detection& det, bool calibrated);

// A line plot of y against x with labelled axes (degrees on x), as a BGR image.
cv::Mat plot_xy(const std::vector<double>& x, const std::vector<double>& y, const std::string& title,
                const std::string& xlabel, const std::string& ylabel, bool points = false);

// Writes DIR/object-N-profile.png (r-theta, Fig. 12), object-N-profile-ref.png (at the reference orientation,
// Figs. 13/17) and object-N-opening.png (D(theta), Fig. 18). false + error if a file cannot be written.
bool write_plots(const DetectedObject& o, const std::string& dir, std::string& error);

}  // namespace rbx1::vision
