// synthetic_board.hpp - test helper: renders a chessboard as a camera with known intrinsics and distortion sees it.
#pragma once
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace rbx1::calib::testing {

struct Camera {
  cv::Size size{640, 480};
  cv::Matx33d k{600, 0, 317.5, 0, 605, 242.25, 0, 0, 1};
  cv::Mat dist = (cv::Mat_<double>(1, 5) << -0.21, 0.06, 0.0012, -0.0008, 0.0);
};

// The board (inner corners `inner`, squares `square_mm`) lies in its plane z=0 with the first inner corner at the
// origin; rvec/tvec place it in front of the camera. Rendering is supersampled 2x2 and the board texture is 8 px
// per mm, and the texture is prefiltered,
// so corners land where projectPoints puts them to about 0.05 px.
// Each supersample pixel (u2, v2) sits at image coordinate ((u2 - 0.5) / 2, (v2 - 0.5) / 2); its ray through the
// lens (normalized, undistorted) is the same for every view, so it is computed once per camera.
inline const std::vector<cv::Point2d>& supersample_rays(const Camera& cam) {
  static std::vector<cv::Point2d> norm;
  static cv::Size done;
  if (done == cam.size && !norm.empty()) return norm;
  const cv::Size big(cam.size.width * 2, cam.size.height * 2);
  std::vector<cv::Point2d> px;
  px.reserve(static_cast<size_t>(big.area()));
  for (int v = 0; v < big.height; ++v)
    for (int u = 0; u < big.width; ++u) px.emplace_back((u - 0.5) / 2.0, (v - 0.5) / 2.0);
  cv::undistortPoints(px, norm, cv::Mat(cam.k), cam.dist, cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 40, 1e-12));
  done = cam.size;
  return norm;
}

// Tests use one Camera (the default), which is what the ray cache assumes.
inline cv::Mat render_board(const Camera& cam, cv::Size inner, double square_mm, const cv::Vec3d& rvec,
                            const cv::Vec3d& tvec) {
  constexpr double kTexPerMm = 8.0;
  const int squares_x = inner.width + 1, squares_y = inner.height + 1;
  const double margin_mm = square_mm;  // white frame round the board, as findChessboardCorners wants
  const double x0 = -square_mm - margin_mm, y0 = -square_mm - margin_mm;
  const double w_mm = squares_x * square_mm + 2 * margin_mm, h_mm = squares_y * square_mm + 2 * margin_mm;
  cv::Mat tex(static_cast<int>(h_mm * kTexPerMm), static_cast<int>(w_mm * kTexPerMm), CV_8U, cv::Scalar(235));
  for (int r = 0; r < squares_y; ++r)
    for (int c = 0; c < squares_x; ++c)
      if ((r + c) % 2 == 0) {
        const cv::Point tl(static_cast<int>((margin_mm + c * square_mm) * kTexPerMm),
                           static_cast<int>((margin_mm + r * square_mm) * kTexPerMm));
        const cv::Point br(static_cast<int>((margin_mm + (c + 1) * square_mm) * kTexPerMm),
                           static_cast<int>((margin_mm + (r + 1) * square_mm) * kTexPerMm));
        cv::rectangle(tex, cv::Rect(tl, br), cv::Scalar(25), cv::FILLED);
      }
  // Prefilter to the supersample footprint (about 2 texels): point-sampling a hard step would alias edges by up
  // to 0.15 px; a symmetric blur keeps every edge where it is and brings corner errors below 0.05 px.
  cv::GaussianBlur(tex, tex, cv::Size(0, 0), 4.0);

  const cv::Size big(cam.size.width * 2, cam.size.height * 2);
  const std::vector<cv::Point2d>& norm = supersample_rays(cam);
  cv::Matx33d rot;
  cv::Rodrigues(rvec, rot);
  // Board plane -> normalized image: [r1 r2 t]; its inverse maps each ray to the board point it hits.
  const cv::Matx33d hbn(rot(0, 0), rot(0, 1), tvec[0], rot(1, 0), rot(1, 1), tvec[1], rot(2, 0), rot(2, 1), tvec[2]);
  const cv::Matx33d inv = hbn.inv();
  cv::Mat map_x(big, CV_32F), map_y(big, CV_32F);
  for (int v = 0; v < big.height; ++v)
    for (int u = 0; u < big.width; ++u) {
      const cv::Point2d& n = norm[static_cast<size_t>(v) * big.width + u];
      const cv::Vec3d b = inv * cv::Vec3d(n.x, n.y, 1.0);
      map_x.at<float>(v, u) = static_cast<float>((b[0] / b[2] - x0) * kTexPerMm - 0.5);
      map_y.at<float>(v, u) = static_cast<float>((b[1] / b[2] - y0) * kTexPerMm - 0.5);
    }
  cv::Mat hi, out;
  cv::remap(tex, hi, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(128));
  cv::resize(hi, out, cam.size, 0, 0, cv::INTER_AREA);
  return out;
}

// Nine poses of a 9x6 board of 20 mm squares, 0.33-0.36 m away: centred, in each image corner (where the lens
// distortion is largest, so it is well constrained) and tilted about both axes.
inline std::vector<std::pair<cv::Vec3d, cv::Vec3d>> board_poses() {
  return {{{0.0, 0.0, 0.0}, {-80, -50, 330}},      {{0.2, -0.2, 0.05}, {-170, -110, 330}},
          {{-0.2, -0.2, -0.05}, {-5, -110, 330}},  {{0.2, 0.2, 0.05}, {-170, 0, 330}},
          {{-0.2, 0.2, -0.05}, {-15, -5, 330}},    {{0.45, 0.0, 0.0}, {-80, -50, 360}},
          {{0.0, 0.45, 0.2}, {-80, -50, 360}},     {{0.2, -0.3, 0.5}, {-60, -80, 360}},
          {{-0.3, -0.1, -0.4}, {-90, -30, 340}}};
}

}  // namespace rbx1::calib::testing
