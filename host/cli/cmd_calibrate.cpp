// cmd_calibrate.cpp - `rbx1 calibrate`: chessboard intrinsics and the table homography into a calibration file.
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "calibration.hpp"
#include "image_io.hpp"
#include "commands.hpp"

namespace rbx1::cli {
namespace {

namespace fs = std::filesystem;
using namespace rbx1::calib;

struct CalibrateArgs {
  std::string chessboard_dir;
  std::string board = "9x6";
  double square_mm = 0;
  std::string table_points;
  double px_per_cm = 0;
  std::string out;
};

// One clear line, exit 2 (shared/DESIGN.md).
int fail(const std::string& message) {
  std::fprintf(stderr, "rbx1 calibrate: %s\n", message.c_str());
  return 2;
}

bool parse_board(const std::string& text, cv::Size& size) {
  int w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X')) return false;
  size = {w, h};
  return w >= 2 && h >= 2 && w <= 100 && h <= 100;
}

bool is_image(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp" || ext == ".tif" || ext == ".tiff" ||
         ext == ".pgm" || ext == ".ppm";
}

int run(const CalibrateArgs& a) {
  if (a.table_points.empty() == (a.px_per_cm <= 0))
    return fail("give exactly one of --table-points FILE and --px-per-cm S (the table plane)");
  Calibration c;
  if (!a.chessboard_dir.empty()) {
    cv::Size inner;
    if (!parse_board(a.board, inner)) return fail("--board must be COLSxROWS inner corners, e.g. 9x6, got '" + a.board + "'");
    if (!(a.square_mm > 0)) return fail("--square-mm must be given and positive with --chessboard");
    std::error_code ec;
    if (!fs::is_directory(a.chessboard_dir, ec)) return fail(a.chessboard_dir + ": not a folder");
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(a.chessboard_dir, ec))
      if (e.is_regular_file() && is_image(e.path())) files.push_back(e.path());
    if (ec) return fail(a.chessboard_dir + ": " + ec.message());
    std::sort(files.begin(), files.end());
    if (files.empty()) return fail(a.chessboard_dir + ": no images (.png, .jpg, .bmp, .tif, .pgm)");
    std::vector<cv::Mat> images;
    for (const auto& f : files) {
      cv::Mat img;
      std::string why;  // read_image keeps libpng's and libjpeg's own messages off stderr
      if (!rbx1::vision::read_image(f.string(), img, why)) return fail(why);
      images.push_back(rbx1::vision::to_gray8(img));
    }
    IntrinsicsResult res;
    std::string error;
    if (!calibrate_intrinsics(images, inner, a.square_mm, res, error)) return fail(a.chessboard_dir + ": " + error);
    c.camera_matrix = res.camera_matrix;
    c.dist_coeffs = res.dist_coeffs;
    c.image_size = res.image_size;
    std::printf("intrinsics: %d of %zu views, RMS reprojection %.3f px, fx %.2f fy %.2f cx %.2f cy %.2f\n",
                res.views_used, images.size(), res.rms_px, res.camera_matrix.at<double>(0, 0),
                res.camera_matrix.at<double>(1, 1), res.camera_matrix.at<double>(0, 2),
                res.camera_matrix.at<double>(1, 2));
    for (int i : res.views_rejected)
      std::printf("  no %s board in %s (skipped)\n", a.board.c_str(), files[static_cast<size_t>(i)].c_str());
  }
  if (a.px_per_cm > 0) {
    c.homography = from_px_per_cm(a.px_per_cm).homography;
    std::printf("table: %.4g px per cm, origin at the top-left pixel\n", a.px_per_cm);
  } else {
    std::vector<TablePoint> points;
    std::string error;
    if (!load_table_points(a.table_points, points, error)) return fail(error);
    double rms = 0;
    if (!fit_table_homography(c, points, rms, error)) return fail(a.table_points + ": " + error);
    std::printf("table: homography from %zu points, RMS residual %.4f cm, %.2f px per cm at the image centre\n",
                points.size(), rms,
                c.px_per_cm_at(c.image_size.area() > 0 ? cv::Point2d(c.image_size.width / 2.0, c.image_size.height / 2.0)
                                                       : points[0].px));
  }
  std::string error;
  if (!save_calibration(a.out, c, error)) return fail(error);
  std::printf("wrote %s\n", a.out.c_str());
  return 0;
}

}  // namespace

void add_calibrate_commands(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<CalibrateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "calibrate", "camera intrinsics from chessboard images and the table plane, written to a calibration file");
  cmd->add_option("--chessboard", args->chessboard_dir, "folder of chessboard images (optional: no undistortion)");
  cmd->add_option("--board", args->board, "inner corners COLSxROWS")->capture_default_str();
  cmd->add_option("--square-mm", args->square_mm, "chessboard square size in mm");
  cmd->add_option("--table-points", args->table_points,
                  "JSON {\"points\": [{\"px\": [x, y], \"cm\": [x, y]}, ...]}: >= 4 known table points, px in the raw "
                  "camera image");
  cmd->add_option("--px-per-cm", args->px_per_cm, "pure scale instead of table points");
  cmd->add_option("--out", args->out, "calibration file to write (atomically)")->required();
  cmd->callback([args, &exit_code] { exit_code = run(*args); });
}

}  // namespace rbx1::cli
