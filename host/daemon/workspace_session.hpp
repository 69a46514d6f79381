// workspace_session.hpp - one workspace calibration in progress: the markers seen at the scan pose and the touch
// points recorded so far. Lives in the daemon between requests until saved or cancelled (workspace_jobs.cpp).
#pragma once
#include <map>

#include <opencv2/core.hpp>

#include "markers.hpp"
#include "workspace_fit.hpp"

namespace rbx1::daemon {

struct WorkspaceSession {
  std::vector<calib::DetectedMarker> markers;  // at the scan pose, undistorted pixels, by id
  cv::Size image_size;
  struct Touch {
    cv::Point2d mm;  // the tool point in the base frame when recorded
    double z_mm = 0;
  };
  std::map<int, Touch> touched;  // by marker id
};

}  // namespace rbx1::daemon
