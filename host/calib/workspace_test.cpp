// workspace_test.cpp - marker sheets (true scale, detectable), marker centres under perspective, the workspace fit
// (exact recovery, noise, leave-one-out, refusals) and its file.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "markers.hpp"
#include "workspace_fit.hpp"

namespace fs = std::filesystem;
using namespace rbx1::calib;

namespace {

fs::path temp_dir() {
  fs::path d = fs::temp_directory_path() / ("rbx1_workspace_test_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

// A camera a few degrees off vertical: pixel -> mm through a known homography.
cv::Matx33d truth_h() {
  return cv::Matx33d(0.0, -0.25, 370.0, -0.25, 0.0, 100.0, 0.0, 0.0, 1.0) *
         cv::Matx33d(1.0, 0.01, 2.0, -0.02, 1.0, -3.0, 4e-5, -3e-5, 1.0);
}

std::vector<WorkspacePoint> grid_points(const cv::Matx33d& h, int n) {
  std::vector<WorkspacePoint> pts;
  const cv::Point2d px[] = {{100, 80}, {700, 90}, {690, 520}, {110, 510}, {400, 300}, {250, 200}, {550, 420}, {400, 100}};
  for (int i = 0; i < n; ++i) pts.push_back({i, px[i], apply_map(h, px[i])});
  return pts;
}

}  // namespace

TEST(MarkerSheet, PngIsTrueScaleAndEveryMarkerIsFound) {
  fs::path dir = temp_dir();
  SheetOptions o;
  o.ids = {0, 1, 2, 3, 4, 5};
  o.dpi = 150;
  std::string error;
  ASSERT_TRUE(write_marker_sheet_png((dir / "sheet.png").string(), o, error)) << error;
  std::string bytes = slurp(dir / "sheet.png");
  size_t at = bytes.find("pHYs");
  ASSERT_NE(at, std::string::npos);
  auto be32 = [&](size_t i) {
    return (uint32_t(uint8_t(bytes[i])) << 24) | (uint32_t(uint8_t(bytes[i + 1])) << 16) |
           (uint32_t(uint8_t(bytes[i + 2])) << 8) | uint32_t(uint8_t(bytes[i + 3]));
  };
  EXPECT_EQ(be32(at + 4), 5906u);  // 150 dpi = 5905.5 px/m
  cv::Mat page = cv::imread((dir / "sheet.png").string(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(page.empty());
  EXPECT_EQ(page.cols, 1240);  // 210 mm at 150 dpi
  EXPECT_EQ(page.rows, 1754);
  std::vector<DetectedMarker> found;
  std::vector<int> dup;
  ASSERT_TRUE(detect_markers(page, o.dictionary, found, dup, error)) << error;
  ASSERT_EQ(found.size(), 6u);
  for (int i = 0; i < 6; ++i) {
    EXPECT_EQ(found[i].id, i);
    // The side: 40 mm = 236.2 px at 150 dpi.
    EXPECT_NEAR(cv::norm(found[i].corners[1] - found[i].corners[0]), 40.0 * 150 / 25.4, 2.0);
  }
  fs::remove_all(dir);
}

TEST(MarkerSheet, PdfIsWellFormedAndRefusesWhatDoesNotFit) {
  fs::path dir = temp_dir();
  SheetOptions o;
  std::string error;
  ASSERT_TRUE(write_marker_sheet_pdf((dir / "sheet.pdf").string(), o, error)) << error;
  std::string pdf = slurp(dir / "sheet.pdf");
  EXPECT_EQ(pdf.rfind("%PDF-1.4", 0), 0u);
  // Every xref offset points at its object.
  size_t x = pdf.find("xref\n0 6\n");
  ASSERT_NE(x, std::string::npos);
  for (int i = 1; i <= 5; ++i) {
    size_t off = std::stoul(pdf.substr(x + 9 + 20 * i, 10));
    EXPECT_EQ(pdf.substr(off, std::to_string(i).size() + 6), std::to_string(i) + " 0 obj") << i;
  }
  EXPECT_NE(pdf.find("/MediaBox [0 0 595.276 841.890]"), std::string::npos);  // A4 in points
  // The scale bar: 100 mm = 283.465 pt.
  EXPECT_NE(pdf.find(" 283.465 5.669 re"), std::string::npos);
  o.ids.assign(40, 0);
  EXPECT_FALSE(write_marker_sheet_pdf((dir / "big.pdf").string(), o, error));
  EXPECT_NE(error.find("do not fit on A4"), std::string::npos) << error;
  o.ids = {60};
  EXPECT_FALSE(write_marker_sheet_pdf((dir / "bad.pdf").string(), o, error));
  EXPECT_NE(error.find("not in 4X4_50"), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(dir / "bad.pdf"));
  fs::remove_all(dir);
}

TEST(MarkerDetect, CentreIsTheDiagonalsIntersectionUnderPerspective) {
  cv::Mat cells;
  std::string error;
  ASSERT_TRUE(marker_cells("4X4_50", 7, cells, error));
  cv::Mat marker;
  cv::resize(cells, marker, cv::Size(300, 300), 0, 0, cv::INTER_NEAREST);
  cv::Mat src(500, 500, CV_8U, cv::Scalar(255));
  marker.copyTo(src(cv::Rect(100, 100, 300, 300)));
  // A strong perspective: the square's centre (250, 250) is not the mean of its corners in the image.
  std::vector<cv::Point2f> from{{99.5f, 99.5f}, {399.5f, 99.5f}, {399.5f, 399.5f}, {99.5f, 399.5f}};
  std::vector<cv::Point2f> to{{120, 110}, {380, 140}, {360, 330}, {140, 380}};
  cv::Mat h = cv::getPerspectiveTransform(from, to);
  cv::Mat img;
  cv::warpPerspective(src, img, h, src.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(255));
  std::vector<DetectedMarker> found;
  std::vector<int> dup;
  ASSERT_TRUE(detect_markers(img, "4X4_50", found, dup, error));
  ASSERT_EQ(found.size(), 1u);
  std::vector<cv::Point2d> c{{249.5, 249.5}}, expect;
  cv::perspectiveTransform(c, expect, h);
  EXPECT_NEAR(found[0].centre.x, expect[0].x, 0.3);
  EXPECT_NEAR(found[0].centre.y, expect[0].y, 0.3);
  cv::Point2d mean(0, 0);
  for (auto& p : found[0].corners) mean += p * 0.25;
  EXPECT_GT(cv::norm(mean - expect[0]), 2.0);  // the naive centre would be off
  EXPECT_FALSE(detect_markers(img, "7X7_9", found, dup, error));
}

TEST(WorkspaceFit, RecoversAPerspectiveMapExactly) {
  cv::Matx33d h = truth_h();
  WorkspaceFit f;
  FitRefusal code{};
  std::string error;
  ASSERT_TRUE(fit_workspace(grid_points(h, 8), 4, f, code, error)) << error;
  EXPECT_EQ(f.model, "homography");
  // Exact up to the solver's tolerance: nanometres.
  EXPECT_LT(f.rms_mm, 1e-4);
  EXPECT_LT(f.max_loo_mm, 1e-3);
  cv::Point2d p(333, 222);
  EXPECT_LT(cv::norm(apply_map(f.h, p) - apply_map(h, p)), 1e-4);
}

TEST(WorkspaceFit, NoiseShowsInRmsAndAnOutlierInItsLeaveOneOut) {
  cv::Matx33d h = truth_h();
  auto pts = grid_points(h, 8);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.1);
  for (auto& p : pts) p.mm += cv::Point2d(noise(rng), noise(rng));
  WorkspaceFit f;
  FitRefusal code{};
  std::string error;
  ASSERT_TRUE(fit_workspace(pts, 4, f, code, error)) << error;
  EXPECT_GT(f.rms_mm, 0.02);
  EXPECT_LT(f.rms_mm, 0.2);
  pts[5].mm += cv::Point2d(4.0, 0.0);  // the operator touched 4 mm off one marker
  ASSERT_TRUE(fit_workspace(pts, 4, f, code, error)) << error;
  int worst = int(std::max_element(f.loo_mm.begin(), f.loo_mm.end()) - f.loo_mm.begin());
  EXPECT_EQ(worst, 5);
  EXPECT_GT(f.loo_mm[5], 3.0);
}

TEST(WorkspaceFit, FourPointsFitAnAffineMap) {
  cv::Matx33d a(0.0, -0.25, 370.0, -0.25, 0.0, 100.0, 0, 0, 1);
  WorkspaceFit f;
  FitRefusal code{};
  std::string error;
  ASSERT_TRUE(fit_workspace(grid_points(a, 4), 4, f, code, error)) << error;
  EXPECT_EQ(f.model, "affine");
  EXPECT_LT(f.rms_mm, 1e-9);
  EXPECT_LT(f.max_loo_mm, 1e-6);
}

TEST(WorkspaceFit, RefusesTooFewCollinearAndDuplicateMarkers) {
  cv::Matx33d h = truth_h();
  WorkspaceFit f;
  FitRefusal code{};
  std::string error;
  EXPECT_FALSE(fit_workspace(grid_points(h, 3), 4, f, code, error));
  EXPECT_EQ(code, FitRefusal::TooFewMarkers);
  EXPECT_FALSE(fit_workspace(grid_points(h, 5), 6, f, code, error));
  EXPECT_EQ(code, FitRefusal::TooFewMarkers);
  EXPECT_NE(error.find("at least 6"), std::string::npos) << error;
  std::vector<WorkspacePoint> line;
  for (int i = 0; i < 6; ++i) {
    cv::Point2d px(100 + 100 * i, 100 + 60 * i + (i % 2) * 2);  // 2 px off a line
    line.push_back({i, px, apply_map(h, px)});
  }
  EXPECT_FALSE(fit_workspace(line, 4, f, code, error));
  EXPECT_EQ(code, FitRefusal::Degenerate);
  EXPECT_NE(error.find("collinear"), std::string::npos) << error;
  auto dup = grid_points(h, 6);
  dup[3].id = 1;
  EXPECT_FALSE(fit_workspace(dup, 4, f, code, error));
  EXPECT_EQ(code, FitRefusal::DuplicateMarker);
}

TEST(WorkspaceFile, RoundTripAndCorruptFilesRejected) {
  fs::path dir = temp_dir();
  WorkspaceCalibration c;
  c.points = grid_points(truth_h(), 6);
  FitRefusal code{};
  std::string error;
  ASSERT_TRUE(fit_workspace(c.points, 4, c.fit, code, error));
  c.image_size = {800, 600};
  c.table_z_mm = -1.25;
  std::string path = (dir / "workspace.json").string();
  ASSERT_TRUE(save_workspace(path, c, error)) << error;
  WorkspaceCalibration back;
  ASSERT_TRUE(load_workspace(path, back, error)) << error;
  EXPECT_EQ(back.image_size, cv::Size(800, 600));
  ASSERT_TRUE(back.table_z_mm.has_value());
  EXPECT_DOUBLE_EQ(*back.table_z_mm, -1.25);
  EXPECT_EQ(back.points.size(), 6u);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) EXPECT_DOUBLE_EQ(back.fit.h(r, k), c.fit.h(r, k));
  const char* bad[] = {"", "{", "[]", R"({"format":"x","version":1})", R"({"format":"rbx1-workspace","version":2})",
                       R"({"format":"rbx1-workspace","version":1,"homography":[[1,0],[0,1]]})",
                       R"({"format":"rbx1-workspace","version":1,"homography":[[0,0,0],[0,0,0],[0,0,0]],"image_size":[8,6],"rms_mm":0})",
                       R"({"format":"rbx1-workspace","version":1,"homography":[[1,0,0],[0,1,0],[0,0,1]],"image_size":[0,6],"rms_mm":0})",
                       R"({"format":"rbx1-workspace","version":1,"homography":[[1,0,0],[0,1,0],[0,0,1]],"image_size":[8,6],"rms_mm":0,"table_z_mm":"low"})"};
  for (const char* text : bad) {
    std::ofstream(dir / "bad.json") << text;
    WorkspaceCalibration keep = back;
    EXPECT_FALSE(load_workspace((dir / "bad.json").string(), keep, error)) << text;
    EXPECT_EQ(error.rfind((dir / "bad.json").string() + ": ", 0), 0u) << error;
    EXPECT_EQ(keep.points.size(), 6u);
  }
  fs::remove_all(dir);
}
