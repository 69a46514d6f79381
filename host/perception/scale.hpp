// scale.hpp - pixels to table centimetres: a calibration file (host/calib), a plain px-per-cm scale, or none.
#pragma once
#include <memory>
#include <string>

#include <opencv2/core.hpp>

namespace rbx1::vision {

class TableScale {
 public:
  virtual ~TableScale() = default;
  virtual cv::Mat undistort(const cv::Mat& image) const = 0;
  virtual cv::Point2d to_cm(cv::Point2d px) const = 0;
  virtual double distance_cm(cv::Point2d a, cv::Point2d b) const = 0;
  virtual double px_per_cm_at(cv::Point2d px) const = 0;
};

// px_per_cm > 0: a pure scale with the origin at the top-left pixel centre.
std::unique_ptr<TableScale> scale_from_px_per_cm(double px_per_cm);
// A calibration file made by `rbx1 calibrate`; null + error "PATH: reason".
std::unique_ptr<TableScale> scale_from_file(const std::string& path, std::string& error);

}  // namespace rbx1::vision
