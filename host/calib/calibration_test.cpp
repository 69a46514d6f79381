// calibration_test.cpp - intrinsics recovered from rendered chessboards, undistortion, homography and scale maths.
#include <gtest/gtest.h>

#include <cmath>

#include "calibration.hpp"
#include "synthetic_board.hpp"

namespace rbx1::calib {
namespace {

using testing::Camera;

const cv::Size kInner{9, 6};
constexpr double kSquareMm = 20.0;

std::vector<cv::Point2f> true_corners(const Camera& cam, const cv::Mat& dist, const cv::Vec3d& r, const cv::Vec3d& t) {
  std::vector<cv::Point3f> board;
  for (int y = 0; y < kInner.height; ++y)
    for (int x = 0; x < kInner.width; ++x)
      board.emplace_back(static_cast<float>(x * kSquareMm), static_cast<float>(y * kSquareMm), 0.f);
  std::vector<cv::Point2f> px;
  cv::projectPoints(board, r, t, cv::Mat(cam.k), dist, px);
  return px;
}

TEST(Intrinsics, RenderedBoardsStayInsideTheImage) {
  const Camera cam;
  for (const auto& [r, t] : testing::board_poses())
    for (const auto& p : true_corners(cam, cam.dist, r, t)) {
      EXPECT_GT(p.x, 15);
      EXPECT_GT(p.y, 15);
      EXPECT_LT(p.x, cam.size.width - 15);
      EXPECT_LT(p.y, cam.size.height - 15);
    }
}

TEST(Intrinsics, CornersFoundWhereTheCameraModelPutsThem) {
  const Camera cam;
  const auto [r, t] = testing::board_poses()[5];
  const cv::Mat img = testing::render_board(cam, kInner, kSquareMm, r, t);
  std::vector<cv::Point2f> found;
  ASSERT_TRUE(find_chessboard(img, kInner, found));
  const auto truth = true_corners(cam, cam.dist, r, t);
  ASSERT_EQ(found.size(), truth.size());
  double worst = 0;
  for (size_t i = 0; i < found.size(); ++i) worst = std::max(worst, cv::norm(found[i] - truth[i]));
  EXPECT_LT(worst, 0.1);
}

TEST(Intrinsics, RecoveredFromSyntheticViews) {
  const Camera cam;
  std::vector<cv::Mat> views;
  for (const auto& [r, t] : testing::board_poses()) views.push_back(testing::render_board(cam, kInner, kSquareMm, r, t));
  views.push_back(cv::Mat(cam.size, CV_8U, cv::Scalar(200)));  // no board: rejected, not fatal
  IntrinsicsResult res;
  std::string error;
  ASSERT_TRUE(calibrate_intrinsics(views, kInner, kSquareMm, res, error)) << error;
  EXPECT_EQ(res.views_used, 9);
  ASSERT_EQ(res.views_rejected.size(), 1u);
  EXPECT_EQ(res.views_rejected[0], 9);
  EXPECT_EQ(res.image_size, cam.size);
  EXPECT_LT(res.rms_px, 0.1);
  const cv::Matx33d k(res.camera_matrix);
  EXPECT_NEAR(k(0, 0), cam.k(0, 0), 0.005 * cam.k(0, 0));
  EXPECT_NEAR(k(1, 1), cam.k(1, 1), 0.005 * cam.k(1, 1));
  EXPECT_NEAR(k(0, 2), cam.k(0, 2), 1.5);
  EXPECT_NEAR(k(1, 2), cam.k(1, 2), 1.5);
  EXPECT_NEAR(res.dist_coeffs.at<double>(0), cam.dist.at<double>(0), 0.02);
  EXPECT_NEAR(res.dist_coeffs.at<double>(1), cam.dist.at<double>(1), 0.08);

  // The recovered model reprojects: a pixel's undistorted position agrees with the truth's across the image.
  std::vector<cv::Point2d> grid;
  for (int y = 40; y <= 440; y += 50)
    for (int x = 40; x <= 600; x += 70) grid.emplace_back(x, y);
  std::vector<cv::Point2d> a, b;
  cv::undistortPoints(grid, a, cv::Mat(cam.k), cam.dist, cv::noArray(), cv::Mat(cam.k));
  cv::undistortPoints(grid, b, res.camera_matrix, res.dist_coeffs, cv::noArray(), cv::Mat(cam.k));
  for (size_t i = 0; i < grid.size(); ++i) EXPECT_LT(cv::norm(a[i] - b[i]), 0.5) << grid[i];
}

TEST(Intrinsics, TooFewViewsIsAnError) {
  const Camera cam;
  const auto poses = testing::board_poses();
  std::vector<cv::Mat> views{testing::render_board(cam, kInner, kSquareMm, poses[0].first, poses[0].second),
                             testing::render_board(cam, kInner, kSquareMm, poses[1].first, poses[1].second)};
  IntrinsicsResult res;
  std::string error;
  EXPECT_FALSE(calibrate_intrinsics(views, kInner, kSquareMm, res, error));
  EXPECT_NE(error.find("found in 2 of 2 images"), std::string::npos) << error;
  // A wrong board size finds nothing.
  EXPECT_FALSE(calibrate_intrinsics(views, {7, 5}, kSquareMm, res, error));
  EXPECT_FALSE(calibrate_intrinsics(views, kInner, 0.0, res, error));
  EXPECT_NE(error.find("square"), std::string::npos);
}

TEST(Intrinsics, MixedImageSizesIsAnError) {
  std::vector<cv::Mat> views{cv::Mat(480, 640, CV_8U, cv::Scalar(0)), cv::Mat(240, 320, CV_8U, cv::Scalar(0))};
  IntrinsicsResult res;
  std::string error;
  EXPECT_FALSE(calibrate_intrinsics(views, kInner, kSquareMm, res, error));
  EXPECT_NE(error.find("320x240"), std::string::npos) << error;
}

TEST(Undistort, StraightensTheBoard) {
  const Camera cam;
  const auto [r, t] = testing::board_poses()[3];
  const cv::Mat img = testing::render_board(cam, kInner, kSquareMm, r, t);
  Calibration c = from_px_per_cm(10);
  EXPECT_FALSE(c.has_intrinsics());
  EXPECT_EQ(c.undistort(img).data, img.data);  // unchanged without intrinsics
  c.camera_matrix = cv::Mat(cam.k).clone();
  c.dist_coeffs = cam.dist.clone();
  c.image_size = cam.size;
  ASSERT_TRUE(c.has_intrinsics());
  const cv::Mat flat = c.undistort(img);
  ASSERT_EQ(flat.size(), img.size());
  std::vector<cv::Point2f> found;
  ASSERT_TRUE(find_chessboard(flat, kInner, found));
  const auto ideal = true_corners(cam, cv::Mat::zeros(1, 5, CV_64F), r, t);
  const auto bent = true_corners(cam, cam.dist, r, t);
  double worst = 0, bend = 0;
  for (size_t i = 0; i < found.size(); ++i) {
    worst = std::max(worst, cv::norm(found[i] - ideal[i]));
    bend = std::max(bend, cv::norm(bent[i] - ideal[i]));
  }
  EXPECT_GT(bend, 5.0);  // the distortion is large enough to matter
  EXPECT_LT(worst, 0.15);
}

TEST(Scale, FromPxPerCm) {
  const Calibration c = from_px_per_cm(40.0);
  const cv::Point2d cm = c.to_table_cm({40.0, 80.0});
  EXPECT_DOUBLE_EQ(cm.x, 1.0);
  EXPECT_DOUBLE_EQ(cm.y, 2.0);
  const cv::Point2d origin = c.to_table_cm({0.0, 0.0});
  EXPECT_DOUBLE_EQ(origin.x, 0.0);
  EXPECT_DOUBLE_EQ(origin.y, 0.0);
  EXPECT_NEAR(c.px_per_cm_at({0, 0}), 40.0, 1e-9);
  EXPECT_NEAR(c.px_per_cm_at({913.5, 27.25}), 40.0, 1e-9);
  EXPECT_NEAR(c.distance_cm({10, 10}, {40, 50}), 50.0 / 40.0, 1e-12);
}

// A tilted camera's table homography: maps pixel -> cm with perspective.
cv::Mat tilted_homography() {
  return (cv::Mat_<double>(3, 3) << 0.025, 0.002, -1.5, -0.001, 0.027, -0.8, 0.00002, 0.00004, 1.0);
}

TEST(Scale, LocalScaleMatchesFiniteDifferences) {
  Calibration c;
  c.homography = tilted_homography();
  for (const cv::Point2d p : {cv::Point2d(100, 100), cv::Point2d(600, 400), cv::Point2d(1200, 50)}) {
    const double e = 1e-3;
    const cv::Point2d dx = (c.to_table_cm(p + cv::Point2d(e, 0)) - c.to_table_cm(p - cv::Point2d(e, 0))) / (2 * e);
    const cv::Point2d dy = (c.to_table_cm(p + cv::Point2d(0, e)) - c.to_table_cm(p - cv::Point2d(0, e))) / (2 * e);
    const double area = std::abs(dx.x * dy.y - dx.y * dy.x);
    EXPECT_NEAR(c.px_per_cm_at(p), 1.0 / std::sqrt(area), 1e-4 / std::sqrt(area));
  }
  EXPECT_GT(c.px_per_cm_at({1200, 700}), 0.0);
}

std::vector<TablePoint> points_for(const Calibration& truth, const std::vector<cv::Point2d>& cm, const Camera* cam) {
  // cm -> undistorted px by the inverse homography, then (with a camera) -> raw px through the lens model.
  cv::Mat inv = truth.homography.inv();
  std::vector<cv::Point2d> und;
  cv::perspectiveTransform(cm, und, inv);
  std::vector<cv::Point2d> raw = und;
  if (cam) {
    std::vector<cv::Point3d> rays;
    for (const auto& p : und)
      rays.emplace_back((p.x - cam->k(0, 2)) / cam->k(0, 0), (p.y - cam->k(1, 2)) / cam->k(1, 1), 1.0);
    cv::projectPoints(rays, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cv::Mat(cam->k), cam->dist, raw);
  }
  std::vector<TablePoint> out;
  for (size_t i = 0; i < cm.size(); ++i) out.push_back({raw[i], cm[i]});
  return out;
}

TEST(Homography, RoundTripWithoutIntrinsics) {
  Calibration truth;
  truth.homography = tilted_homography();
  const std::vector<cv::Point2d> cm{{0, 0}, {12, 0}, {12, 12}, {0, 12}, {6, 6}, {3, 9}};
  Calibration fit;
  double rms = -1;
  std::string error;
  ASSERT_TRUE(fit_table_homography(fit, points_for(truth, cm, nullptr), rms, error)) << error;
  EXPECT_LT(rms, 1e-5);  // exact data: what is left is findHomography's numerics (well below a micron)
  for (const cv::Point2d p : {cv::Point2d(50, 60), cv::Point2d(640, 360), cv::Point2d(1000, 650)}) {
    const cv::Point2d a = fit.to_table_cm(p), b = truth.to_table_cm(p);
    EXPECT_NEAR(a.x, b.x, 1e-5);
    EXPECT_NEAR(a.y, b.y, 1e-5);
  }
}

TEST(Homography, RawPixelsAreUndistortedFirst) {
  const Camera cam;
  Calibration truth;
  truth.homography = (cv::Mat_<double>(3, 3) << 0.05, 0.001, -3.0, 0.0005, 0.049, -2.0, 0.00001, 0.00002, 1.0);
  const std::vector<cv::Point2d> cm{{1, 1}, {20, 1}, {20, 16}, {1, 16}, {10, 8}};
  const auto pts = points_for(truth, cm, &cam);
  Calibration fit;
  fit.camera_matrix = cv::Mat(cam.k).clone();
  fit.dist_coeffs = cam.dist.clone();
  fit.image_size = cam.size;
  double rms = -1;
  std::string error;
  ASSERT_TRUE(fit_table_homography(fit, pts, rms, error)) << error;
  EXPECT_LT(rms, 1e-4);
  const cv::Point2d a = fit.to_table_cm({320, 240}), b = truth.to_table_cm({320, 240});
  EXPECT_NEAR(a.x, b.x, 1e-3);
  EXPECT_NEAR(a.y, b.y, 1e-3);
  // Ignoring the lens would fit badly: the raw pixels are not a homography's image.
  Calibration naive;
  ASSERT_TRUE(fit_table_homography(naive, pts, rms, error)) << error;
  EXPECT_GT(rms, 0.01);
}

TEST(Homography, BadPointSetsAreErrors) {
  Calibration c;
  double rms = 0;
  std::string error;
  std::vector<TablePoint> three{{{0, 0}, {0, 0}}, {{100, 0}, {1, 0}}, {{0, 100}, {0, 1}}};
  EXPECT_FALSE(fit_table_homography(c, three, rms, error));
  EXPECT_NE(error.find("at least 4 points, got 3"), std::string::npos) << error;
  std::vector<TablePoint> line{{{0, 0}, {0, 0}}, {{100, 0}, {1, 0}}, {{200, 0}, {2, 0}}, {{300, 0}, {3, 0}}};
  EXPECT_FALSE(fit_table_homography(c, line, rms, error));
  EXPECT_NE(error.find("collinear"), std::string::npos) << error;
  EXPECT_TRUE(c.homography.empty());
}

}  // namespace
}  // namespace rbx1::calib
