// calibration_file_test.cpp - the calibration JSON file: round trips, atomic replace, and every kind of bad file.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "calibration.hpp"

namespace rbx1::calib {
namespace {

namespace fs = std::filesystem;

class CalibFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("rbx1_calib_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(path(name)) << text;
    return path(name);
  }
  fs::path dir_;
};

Calibration full() {
  Calibration c;
  c.camera_matrix = (cv::Mat_<double>(3, 3) << 600.25, 0, 317.5, 0, 605.125, 242.25, 0, 0, 1);
  c.dist_coeffs = (cv::Mat_<double>(1, 5) << -0.21, 0.06, 0.0012, -0.0008, 0.001);
  c.image_size = {640, 480};
  c.homography = (cv::Mat_<double>(3, 3) << 0.025, 0.002, -1.5, -0.001, 0.027, -0.8, 0.00002, 0.00004, 1.0);
  return c;
}

const char* kGood = R"({"format": "rbx1-calibration", "version": 1,
  "homography": [[0.025, 0, 0], [0, 0.025, 0], [0, 0, 1]],
  "camera_matrix": [[600, 0, 320], [0, 600, 240], [0, 0, 1]],
  "dist_coeffs": [-0.2, 0.05, 0, 0, 0], "image_size": [640, 480]})";

TEST_F(CalibFile, RoundTripWithIntrinsics) {
  const Calibration c = full();
  std::string error;
  ASSERT_TRUE(save_calibration(path("c.json"), c, error)) << error;
  Calibration back;
  ASSERT_TRUE(load_calibration(path("c.json"), back, error)) << error;
  ASSERT_TRUE(back.has_intrinsics());
  EXPECT_EQ(cv::norm(back.camera_matrix, c.camera_matrix, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(back.dist_coeffs, c.dist_coeffs, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(back.homography, c.homography, cv::NORM_INF), 0.0);
  EXPECT_EQ(back.image_size, c.image_size);
  // Only the target remains: no temporary file beside it.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator{}), 1);
}

TEST_F(CalibFile, RoundTripScaleOnlyAndOverwrite) {
  std::string error;
  ASSERT_TRUE(save_calibration(path("c.json"), full(), error)) << error;
  ASSERT_TRUE(save_calibration(path("c.json"), from_px_per_cm(37.5), error)) << error;
  Calibration back = full();
  ASSERT_TRUE(load_calibration(path("c.json"), back, error)) << error;
  EXPECT_FALSE(back.has_intrinsics());
  EXPECT_EQ(back.image_size, cv::Size());
  EXPECT_NEAR(back.px_per_cm_at({100, 100}), 37.5, 1e-12);
}

TEST_F(CalibFile, GoodHandWrittenFileLoads) {
  Calibration c;
  std::string error;
  ASSERT_TRUE(load_calibration(write("good.json", kGood), c, error)) << error;
  EXPECT_NEAR(c.to_table_cm({40, 80}).y, 2.0, 1e-12);
  EXPECT_EQ(c.dist_coeffs.cols, 5);
}

TEST_F(CalibFile, SaveIntoMissingFolderFails) {
  std::string error;
  EXPECT_FALSE(save_calibration(path("no/such/dir/c.json"), full(), error));
  EXPECT_EQ(error.rfind(path("no/such/dir/c.json") + ": cannot write", 0), 0u) << error;
  Calibration empty;
  EXPECT_FALSE(save_calibration(path("c.json"), empty, error));
  EXPECT_NE(error.find("homography"), std::string::npos);
}

struct BadCase {
  const char* name;
  std::string text;
  const char* reason;  // must appear in the error
};

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST_F(CalibFile, BadFilesAreRejectedWithTheirReason) {
  const std::string good = kGood;
  const std::vector<BadCase> cases{
      {"empty", "", "not valid JSON"},
      {"truncated", good.substr(0, good.size() / 2), "not valid JSON"},
      {"array", "[1, 2]", "top level must be a JSON object"},
      {"no_format", replace(good, R"("format": "rbx1-calibration", )", ""), "missing field \"format\""},
      {"bad_format", replace(good, "rbx1-calibration", "opencv"), "\"format\" must be"},
      {"no_version", replace(good, R"("version": 1,)", ""), "missing field \"version\""},
      {"version_2", replace(good, R"("version": 1)", R"("version": 2)"), "version 2 is not supported"},
      {"version_str", replace(good, R"("version": 1)", R"("version": "1")"), "\"version\" must be an integer"},
      {"no_homography", replace(good, R"("homography": [[0.025, 0, 0], [0, 0.025, 0], [0, 0, 1]],)", ""),
       "missing field \"homography\""},
      {"short_row", replace(good, "[0, 0.025, 0]", "[0, 0.025]"), "\"homography\" row 1 must be an array of 3"},
      {"string_cell", replace(good, "[0.025, 0, 0]", R"([0.025, "0", 0])"),
       "\"homography\"[0][1] must be a number, got string"},
      {"singular", replace(good, "[0, 0, 1]]", "[0, 0, 0]]"), "\"homography\" is singular"},
      {"no_dist", replace(good, R"("dist_coeffs": [-0.2, 0.05, 0, 0, 0], )", ""), "missing field \"dist_coeffs\""},
      {"half_null", replace(good, "[-0.2, 0.05, 0, 0, 0]", "null"), "all set or all null"},
      {"dist_len", replace(good, "[-0.2, 0.05, 0, 0, 0]", "[-0.2, 0.05, 0]"), "4, 5, 8, 12 or 14"},
      {"dist_type", replace(good, "[-0.2, 0.05, 0, 0, 0]", "[-0.2, true, 0, 0, 0]"),
       "\"dist_coeffs\"[1] must be a number, got boolean"},
      {"neg_focal", replace(good, "[[600, 0, 320]", "[[-600, 0, 320]"), "focal lengths must be positive"},
      {"size_float", replace(good, "[640, 480]", "[640.5, 480]"), "\"image_size\" must be [width, height]"},
      {"size_zero", replace(good, "[640, 480]", "[0, 480]"), "\"image_size\" must be [width, height]"},
  };
  for (const auto& bad : cases) {
    Calibration c = full();
    std::string error;
    const std::string file = write(std::string(bad.name) + ".json", bad.text);
    EXPECT_FALSE(load_calibration(file, c, error)) << bad.name;
    EXPECT_EQ(error.rfind(file + ": ", 0), 0u) << bad.name << ": " << error;
    EXPECT_NE(error.find(bad.reason), std::string::npos) << bad.name << ": " << error;
    // A failed load leaves the caller's calibration alone.
    EXPECT_EQ(cv::norm(c.homography, full().homography, cv::NORM_INF), 0.0) << bad.name;
  }
}

TEST_F(CalibFile, MissingFileIsAnError) {
  Calibration c;
  std::string error;
  EXPECT_FALSE(load_calibration(path("absent.json"), c, error));
  EXPECT_EQ(error, path("absent.json") + ": cannot open: No such file or directory");
}

TEST_F(CalibFile, TablePoints) {
  std::vector<TablePoint> pts;
  std::string error;
  ASSERT_TRUE(load_table_points(
      write("p.json", R"({"points": [{"px": [10.5, 20], "cm": [0, 0]}, {"px": [110, 20], "cm": [2.5, 0]}]})"), pts,
      error))
      << error;
  ASSERT_EQ(pts.size(), 2u);
  EXPECT_EQ(pts[1].px, cv::Point2d(110, 20));
  EXPECT_EQ(pts[1].cm, cv::Point2d(2.5, 0));
  EXPECT_FALSE(load_table_points(write("q.json", R"({"pts": []})"), pts, error));
  EXPECT_NE(error.find("missing field \"points\""), std::string::npos) << error;
  EXPECT_FALSE(load_table_points(write("r.json", R"({"points": [{"px": [1], "cm": [0, 0]}]})"), pts, error));
  EXPECT_NE(error.find("points[0].px must be [x, y]"), std::string::npos) << error;
  EXPECT_FALSE(load_table_points(write("s.json", R"({"points": [{"px": [1, 2]}]})"), pts, error));
  EXPECT_NE(error.find("missing field \"cm\""), std::string::npos) << error;
  EXPECT_EQ(pts.size(), 2u);  // untouched on failure
}

}  // namespace
}  // namespace rbx1::calib
