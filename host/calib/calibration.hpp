// calibration.hpp - camera intrinsics (chessboard), undistortion and the image-to-table homography, with its JSON file.
#pragma once
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace rbx1::calib {

// Everything perception needs to turn pixels into table centimetres.
// Pixel coordinates follow shared/DESIGN.md: x right, y down, origin at the top-left pixel's centre.
struct Calibration {
  cv::Mat camera_matrix, dist_coeffs;  // empty when no intrinsics
  cv::Size image_size;                 // image size the intrinsics belong to (0x0 if none)
  cv::Mat homography;                  // 3x3 CV_64F: undistorted pixel -> table cm
  bool has_intrinsics() const;
  cv::Mat undistort(const cv::Mat& image) const;          // returns image unchanged without intrinsics
  cv::Point2d to_table_cm(cv::Point2d px) const;          // px in the undistorted image
  double distance_cm(cv::Point2d a_px, cv::Point2d b_px) const;
  double px_per_cm_at(cv::Point2d px) const;              // local scale (geometric mean of both axes)
};

Calibration from_px_per_cm(double px_per_cm);             // pure scale; origin at the top-left pixel centre
bool load_calibration(const std::string& path, Calibration& out, std::string& error);  // error "PATH: reason"
bool save_calibration(const std::string& path, const Calibration& c, std::string& error);  // atomic write

// The calibration file's format version; load_calibration rejects any other.
inline constexpr int kFileVersion = 1;

// --- Making a calibration (rbx1 calibrate, tests) ---

// Intrinsics from chessboard views: the pattern's inner-corner grid (e.g. 9x6) and square size.
struct IntrinsicsResult {
  cv::Mat camera_matrix, dist_coeffs;  // 3x3 and 1x5 CV_64F (k1 k2 p1 p2 k3)
  cv::Size image_size;
  double rms_px = 0;                   // RMS reprojection error over all used corners
  int views_used = 0;
  std::vector<int> views_rejected;     // indices of images where the board was not found
};
// Finds the inner corners to sub-pixel accuracy; false when the whole board is not visible.
bool find_chessboard(const cv::Mat& image, cv::Size inner_corners, std::vector<cv::Point2f>& corners);
// Needs >= 3 views with the board found, all of one size. false + error ("reason") otherwise.
bool calibrate_intrinsics(const std::vector<cv::Mat>& images, cv::Size inner_corners, double square_mm,
                          IntrinsicsResult& out, std::string& error);

// A known table point: where it is in the camera image (raw, as captured) and on the table (cm).
struct TablePoint {
  cv::Point2d px;
  cv::Point2d cm;
};
// Reads {"points": [{"px": [x, y], "cm": [x, y]}, ...]}; error "PATH: reason".
bool load_table_points(const std::string& path, std::vector<TablePoint>& out, std::string& error);
// Fits c.homography from >= 4 points (undistorting their px first when c has intrinsics). Rejects degenerate
// sets (collinear points). rms_cm: the fit's RMS residual on the table. false + error ("reason") otherwise.
bool fit_table_homography(Calibration& c, const std::vector<TablePoint>& points, double& rms_cm, std::string& error);

}  // namespace rbx1::calib
