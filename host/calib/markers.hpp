// markers.hpp - the workspace calibration's ArUco markers: the printable sheet (PNG, PDF at true scale) and
// their detection in a camera frame (OpenCV aruco, Debian's contrib package).
#pragma once
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace rbx1::calib {

// Dictionary names as in OpenCV without the DICT_ prefix: "4X4_50", "5X5_100", ...
bool marker_dictionary_known(const std::string& name);
std::string marker_dictionary_names();  // "4X4_50, 4X4_100, ..." for error messages

// The marker image (black and white, 1 px per cell, border included: (size + 2) x (size + 2)).
// false + error for an unknown dictionary or an id outside it.
bool marker_cells(const std::string& dictionary, int id, cv::Mat& cells, std::string& error);

// A sheet of markers on A4 paper, laid out in rows with their ids printed beside them.
struct SheetOptions {
  std::string dictionary = "4X4_50";
  std::vector<int> ids{0, 1, 2, 3, 4, 5};
  double marker_mm = 40.0;  // the black square's side
  int dpi = 300;            // PNG only
};
// PNG with its physical resolution (pHYs) set, so it prints at true scale; PDF with vector squares. Both carry a
// 100 mm scale bar to check the print. Written atomically. false + error ("PATH: reason" or a layout problem).
bool write_marker_sheet_png(const std::string& path, const SheetOptions& o, std::string& error);
bool write_marker_sheet_pdf(const std::string& path, const SheetOptions& o, std::string& error);

// A detected marker: id, its four corners (clockwise from the top-left of the printed marker) and its centre (the
// diagonals' intersection: the image of the square's centre under perspective), in the given image's pixels.
struct DetectedMarker {
  int id = 0;
  std::vector<cv::Point2d> corners;
  cv::Point2d centre;
};
// Every marker of the dictionary in image (BGR or gray), sub-pixel corners, sorted by id. A marker id seen twice
// is dropped with a note in duplicates. false + error for an unknown dictionary or an empty image.
bool detect_markers(const cv::Mat& image, const std::string& dictionary, std::vector<DetectedMarker>& out,
                    std::vector<int>& duplicates, std::string& error);

}  // namespace rbx1::calib
