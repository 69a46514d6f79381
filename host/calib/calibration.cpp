// calibration.cpp - the Calibration's pixel-to-table maths, the chessboard intrinsics and the table homography.
#include "calibration.hpp"

#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace rbx1::calib {

bool Calibration::has_intrinsics() const {
  return !camera_matrix.empty() && !dist_coeffs.empty();
}

cv::Mat Calibration::undistort(const cv::Mat& image) const {
  if (!has_intrinsics() || image.empty()) return image;
  // Same camera matrix for the output, so the undistorted image keeps the scale the homography was fitted in.
  cv::Mat out;
  cv::undistort(image, out, camera_matrix, dist_coeffs, camera_matrix);
  return out;
}

cv::Point2d Calibration::to_table_cm(cv::Point2d px) const {
  const cv::Matx33d h = homography.empty() ? cv::Matx33d::eye() : cv::Matx33d(homography);
  const cv::Vec3d p = h * cv::Vec3d(px.x, px.y, 1.0);
  return {p[0] / p[2], p[1] / p[2]};
}

double Calibration::distance_cm(cv::Point2d a_px, cv::Point2d b_px) const {
  const cv::Point2d d = to_table_cm(a_px) - to_table_cm(b_px);
  return std::hypot(d.x, d.y);
}

double Calibration::px_per_cm_at(cv::Point2d px) const {
  // The homography's Jacobian at px: its determinant is the local area ratio cm^2 per px^2.
  const cv::Matx33d h = homography.empty() ? cv::Matx33d::eye() : cv::Matx33d(homography);
  const double w = h(2, 0) * px.x + h(2, 1) * px.y + h(2, 2);
  const double u = h(0, 0) * px.x + h(0, 1) * px.y + h(0, 2);
  const double v = h(1, 0) * px.x + h(1, 1) * px.y + h(1, 2);
  const double dudx = (h(0, 0) * w - u * h(2, 0)) / (w * w), dudy = (h(0, 1) * w - u * h(2, 1)) / (w * w);
  const double dvdx = (h(1, 0) * w - v * h(2, 0)) / (w * w), dvdy = (h(1, 1) * w - v * h(2, 1)) / (w * w);
  const double det = std::abs(dudx * dvdy - dudy * dvdx);
  return det > 0 ? 1.0 / std::sqrt(det) : 0.0;
}

Calibration from_px_per_cm(double px_per_cm) {
  Calibration c;
  c.homography = cv::Mat::eye(3, 3, CV_64F);
  c.homography.at<double>(0, 0) = 1.0 / px_per_cm;
  c.homography.at<double>(1, 1) = 1.0 / px_per_cm;
  return c;
}

bool find_chessboard(const cv::Mat& image, cv::Size inner_corners, std::vector<cv::Point2f>& corners) {
  cv::Mat gray;
  if (image.channels() == 3) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4) cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  else gray = image;
  corners.clear();
  if (!cv::findChessboardCorners(gray, inner_corners, corners,
                                 cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE)) {
    return false;
  }
  cv::cornerSubPix(gray, corners, cv::Size(5, 5), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-4));
  return true;
}

bool calibrate_intrinsics(const std::vector<cv::Mat>& images, cv::Size inner_corners, double square_mm,
                          IntrinsicsResult& out, std::string& error) {
  out = IntrinsicsResult{};
  if (inner_corners.width < 2 || inner_corners.height < 2) {
    error = "the board needs at least 2x2 inner corners";
    return false;
  }
  if (!(square_mm > 0)) {
    error = "the square size must be positive";
    return false;
  }
  std::vector<cv::Point3f> board;
  for (int r = 0; r < inner_corners.height; ++r)
    for (int c = 0; c < inner_corners.width; ++c)
      board.emplace_back(static_cast<float>(c * square_mm), static_cast<float>(r * square_mm), 0.f);

  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> image_points;
  for (size_t i = 0; i < images.size(); ++i) {
    const cv::Mat& img = images[i];
    if (img.empty()) {
      error = "image " + std::to_string(i) + " is empty";
      return false;
    }
    if (out.image_size.area() == 0) out.image_size = img.size();
    if (img.size() != out.image_size) {
      error = "image " + std::to_string(i) + " is " + std::to_string(img.cols) + "x" + std::to_string(img.rows) +
              ", the first was " + std::to_string(out.image_size.width) + "x" +
              std::to_string(out.image_size.height);
      return false;
    }
    std::vector<cv::Point2f> corners;
    if (!find_chessboard(img, inner_corners, corners)) {
      out.views_rejected.push_back(static_cast<int>(i));
      continue;
    }
    image_points.push_back(std::move(corners));
    object_points.push_back(board);
  }
  out.views_used = static_cast<int>(image_points.size());
  if (out.views_used < 3) {
    error = "the " + std::to_string(inner_corners.width) + "x" + std::to_string(inner_corners.height) +
            " board was found in " + std::to_string(out.views_used) + " of " + std::to_string(images.size()) +
            " images; at least 3 views are needed";
    return false;
  }
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat k, d;
  out.rms_px = cv::calibrateCamera(object_points, image_points, out.image_size, k, d, rvecs, tvecs);
  k.convertTo(out.camera_matrix, CV_64F);
  d.convertTo(out.dist_coeffs, CV_64F);
  out.dist_coeffs = out.dist_coeffs.reshape(1, 1);
  if (!std::isfinite(out.rms_px) || !cv::checkRange(out.camera_matrix) || !cv::checkRange(out.dist_coeffs)) {
    error = "calibration did not converge";
    return false;
  }
  return true;
}

bool fit_table_homography(Calibration& c, const std::vector<TablePoint>& points, double& rms_cm,
                          std::string& error) {
  if (points.size() < 4) {
    error = "a table homography needs at least 4 points, got " + std::to_string(points.size());
    return false;
  }
  std::vector<cv::Point2d> px, cm;
  for (const auto& p : points) {
    px.push_back(p.px);
    cm.push_back(p.cm);
  }
  if (c.has_intrinsics()) {
    std::vector<cv::Point2d> und;
    cv::undistortPoints(px, und, c.camera_matrix, c.dist_coeffs, cv::noArray(), c.camera_matrix);
    px = und;
  }
  // Degenerate sets: a homography needs points spanning an area on both sides (not all on one line).
  auto spans_area = [](const std::vector<cv::Point2d>& pts) {
    std::vector<cv::Point2f> f(pts.begin(), pts.end());
    std::vector<cv::Point2f> hull;
    cv::convexHull(f, hull);
    if (hull.size() < 3) return false;
    const cv::Rect2f box = cv::boundingRect(f);
    const double scale = std::max(box.width, box.height);
    return scale > 0 && cv::contourArea(hull) > 1e-3 * scale * scale;
  };
  if (!spans_area(px) || !spans_area(cm)) {
    error = "the table points are collinear (or coincide); they must span an area";
    return false;
  }
  cv::Mat h = cv::findHomography(px, cm, 0);
  if (h.empty() || !cv::checkRange(h)) {
    error = "no homography fits these table points";
    return false;
  }
  h.convertTo(c.homography, CV_64F);
  double sum = 0;
  for (size_t i = 0; i < px.size(); ++i) {
    const cv::Point2d d = c.to_table_cm(px[i]) - cm[i];
    sum += d.dot(d);
  }
  rms_cm = std::sqrt(sum / static_cast<double>(px.size()));
  return true;
}

}  // namespace rbx1::calib
