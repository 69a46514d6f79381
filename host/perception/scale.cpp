// scale.cpp - TableScale over rbx1::calib::Calibration: a calibration file, or a plain --px-per-cm scale.
#include "scale.hpp"

#include "calibration.hpp"

namespace rbx1::vision {
namespace {

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

}  // namespace

std::unique_ptr<TableScale> scale_from_px_per_cm(double px_per_cm) {
  return std::make_unique<CalibScale>(rbx1::calib::from_px_per_cm(px_per_cm));
}

std::unique_ptr<TableScale> scale_from_file(const std::string& path, std::string& error) {
  rbx1::calib::Calibration c;
  if (!rbx1::calib::load_calibration(path, c, error)) return nullptr;
  return std::make_unique<CalibScale>(std::move(c));
}

}  // namespace rbx1::vision
