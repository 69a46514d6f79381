// scale.cpp - TableScale over rbx1::calib::Calibration (when host/calib is built) or a plain scale.
#include "scale.hpp"

#include <cmath>

#if RBX1_HAVE_CALIB
#include "calibration.hpp"
#endif

namespace rbx1::vision {
namespace {

#if RBX1_HAVE_CALIB
class CalibScale : public TableScale {
 public:
  explicit CalibScale(rbx1::calib::Calibration c) : c_(std::move(c)) {}
  cv::Mat undistort(const cv::Mat& image) const override { return c_.undistort(image); }
  cv::Point2d to_cm(cv::Point2d px) const override { return c_.to_table_cm(px); }
  double distance_cm(cv::Point2d a, cv::Point2d b) const override { return c_.distance_cm(a, b); }
  double px_per_cm_at(cv::Point2d px) const override { return c_.px_per_cm_at(px); }

 private:
  rbx1::calib::Calibration c_;
};
#endif

class PlainScale : public TableScale {
 public:
  explicit PlainScale(double s) : s_(s) {}
  cv::Mat undistort(const cv::Mat& image) const override { return image; }
  cv::Point2d to_cm(cv::Point2d px) const override { return px / s_; }
  double distance_cm(cv::Point2d a, cv::Point2d b) const override { return std::hypot(a.x - b.x, a.y - b.y) / s_; }
  double px_per_cm_at(cv::Point2d) const override { return s_; }

 private:
  double s_;
};

}  // namespace

std::unique_ptr<TableScale> scale_from_px_per_cm(double px_per_cm) {
#if RBX1_HAVE_CALIB
  return std::make_unique<CalibScale>(rbx1::calib::from_px_per_cm(px_per_cm));
#else
  return std::make_unique<PlainScale>(px_per_cm);
#endif
}

std::unique_ptr<TableScale> scale_from_file(const std::string& path, std::string& error) {
#if RBX1_HAVE_CALIB
  rbx1::calib::Calibration c;
  if (!rbx1::calib::load_calibration(path, c, error)) return nullptr;
  return std::make_unique<CalibScale>(std::move(c));
#else
  error = path + ": calibration files need host/calib (not built)";
  return nullptr;
#endif
}

}  // namespace rbx1::vision
