// vision.hpp - the perception entry point: options, the [vision] config table, and one frame -> detect JSON.
#pragma once
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "config.hpp"
#include "detector.hpp"
#include "library.hpp"
#include "scale.hpp"
#include "types.hpp"

namespace rbx1::vision {

struct VisionOptions {
  std::string background_path;   // empty: model the background automatically
  Polarity objects = Polarity::Auto;
  std::string library_path;      // empty: no identification (labels null)
  double px_per_cm = 0;          // 0 and no calibration_path: uncalibrated (cm fields null)
  std::string calibration_path;
  double gripper_max_cm = 5.0;
  double gripper_min_cm = 0.2;   // narrower openings are no grip (calibrated)
  double gripper_min_px = 2;     // the same when uncalibrated
  // Finger geometry for the clearance check: width across the closing line, depth outward from the contact.
  double finger_width_cm = 1.0, finger_depth_cm = 1.0;  // used when calibrated
  double finger_width_px = 0, finger_depth_px = 0;      // used when uncalibrated (0: no check)
  int min_area_px = 0;           // smaller regions are specks; 0: scaled with the frame (min_area_for)
  double match_threshold = 0.5;  // identification score below this: unknown
};

// Reads the [vision] table (keys as the fields above; objects = "auto" | "dark" | "light"); errors name the key.
void parse_vision_config(rbx1::config::Section vision, VisionOptions& out);
// "auto" | "dark" | "light" -> Polarity; false for anything else.
bool parse_polarity(const std::string& text, Polarity& out);

// The speck size for a frame: 40 px at 640x480, in proportion to the frame's area (at least 12 px).
int min_area_for(cv::Size frame);

class Vision {
 public:
  static std::unique_ptr<Vision> create(const VisionOptions&, std::string& error);  // null + error on bad files
  // One frame (BGR or gray) -> the JSON document of `rbx1 detect --json` (shared/DESIGN.md). false + error.
  bool process(const cv::Mat& frame, nlohmann::json& result, std::string& error);

  // The same in parts, for the CLI and the daemon: detection on the processed (undistorted) frame, then its outputs.
  bool run(const cv::Mat& frame, Detection& det, cv::Mat& processed, std::string& error);
  // What the scan reports, its figures rounded as published (scan_json.hpp writes it as the JSON document).
  Scan scan(const Detection& det) const;
  std::string report(const Detection& det) const;  // the paper's Figure 21
  // Object k of det as a library entry (rbx1 teach, the daemon's teach): its identity profile, size and the
  // threshold learnt from its own views (identify.hpp learn_threshold).
  LibraryEntry teach_entry(const Detection& det, size_t k, const std::string& name, bool mirror_ok,
                           SelfViews* views = nullptr) const;
  bool calibrated() const { return scale_ != nullptr; }
  // Where pixel px of the processed frame lies on the table (cm, as objects' centroid_cm); none uncalibrated.
  std::optional<cv::Point2d> table_cm(cv::Point2d px) const {
    return scale_ ? std::optional<cv::Point2d>(scale_->to_cm(px)) : std::nullopt;
  }
  double px_per_cm_at(cv::Point2d px) const { return scale_ ? scale_->px_per_cm_at(px) : 0; }
  const VisionOptions& options() const { return opt_; }
  const DetectorOptions& detector_options() const { return det_; }

 private:
  VisionOptions opt_;
  DetectorOptions det_;
  cv::Mat background_;             // gray, undistorted; empty: automatic
  cv::Mat background_bgr_;         // the same in colour when it is 8-bit BGR (shadow test), else empty
  Library library_;
  bool has_library_ = false;
  std::unique_ptr<TableScale> scale_;
};

}  // namespace rbx1::vision
