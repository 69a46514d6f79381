// workspace_fit.hpp - the workspace calibration's map from (undistorted) image pixels to the arm's base frame at
// table height, fitted to markers whose centres the operator touched with the tool point; its JSON file.
#pragma once
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace rbx1::calib {

// One marker: where the camera saw its centre (undistorted pixels) and where the tool point touched it (base mm).
struct WorkspacePoint {
  int id = 0;
  cv::Point2d px;
  cv::Point2d mm;
};

struct WorkspaceFit {
  std::string model;             // "homography" (5 or more points) or "affine" (exactly 4)
  cv::Matx33d h;                 // pixel -> base mm (homogeneous; affine: last row 0 0 1)
  double rms_mm = 0;             // RMS of the residuals at the fitted points
  std::vector<double> residual_mm;  // per point, in the input order
  std::vector<double> loo_mm;    // per point: its error when the map is fitted without it
  double max_loo_mm = 0;
};

// Least squares over all points, no RANSAC: with a handful of hand-recorded points an outlier must be shown (its
// leave-one-out error) and re-recorded, not silently dropped. Homography for >= 5 points (a camera a few degrees
// off vertical sees the table in perspective); with exactly 4 an affine map, the only model that then still has
// residuals to check. Refuses (why, error): TooFewMarkers (< min_points, < 4), DuplicateMarker, Degenerate (collinear
// or coincident points, in the image or on the table); the daemon names them with its error codes.
enum class FitRefusal { TooFewMarkers, DuplicateMarker, Degenerate };
bool fit_workspace(const std::vector<WorkspacePoint>& points, int min_points, WorkspaceFit& out, FitRefusal& why,
                   std::string& error);

cv::Point2d apply_map(const cv::Matx33d& h, cv::Point2d px);

// The file (state directory workspace.json): {"format": "rbx1-workspace", "version": 1, "model", "homography",
// "image_size", "rms_mm", "max_loo_mm", "points": [{"id", "px", "mm", "residual_mm", "loo_mm"}], "table_z_mm"}.
// table_z_mm (optional): the table's height as the arm's own kinematics reaches it, the mean height of the touches.
struct WorkspaceCalibration {
  WorkspaceFit fit;
  cv::Size image_size;
  std::vector<WorkspacePoint> points;
  std::optional<double> table_z_mm;
};
bool save_workspace(const std::string& path, const WorkspaceCalibration& c, std::string& error);  // atomic
// error "PATH: reason"; out untouched on failure.
bool load_workspace(const std::string& path, WorkspaceCalibration& out, std::string& error);

}  // namespace rbx1::calib
