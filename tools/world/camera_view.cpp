// camera_view.cpp - FK to the camera, projection of the scene's polygons through the lens (OpenCV), light, noise.
#include "camera_view.hpp"

#include <numbers>
#include <algorithm>
#include <cmath>

#include <opencv2/aruco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "kinematics.hpp"

namespace rbx1::world {

namespace {
constexpr int kSuper = 2;         // supersampling per axis: polygons are filled at 2x and averaged down
constexpr int kShift = 4;         // fillPoly's fractional bits
constexpr double kStepMm = 1.5;   // edges are cut into pieces this long so the lens bends them

double rad(double d) { return d * std::numbers::pi / 180.0; }

Eigen::Matrix3d rpy(const std::array<double, 3>& deg) {
  return (Eigen::AngleAxisd(rad(deg[2]), Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(rad(deg[1]), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rad(deg[0]), Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

// Projects 3-D base-frame points; false when any lies behind the camera.
class Projector {
 public:
  Projector(const Camera& cam, const Eigen::Isometry3d& pose) : inv_(pose.inverse()) {
    k_ = (cv::Mat_<double>(3, 3) << cam.fx * kSuper, 0, cam.cx * kSuper + (kSuper - 1) / 2.0, 0, cam.fy * kSuper,
          cam.cy * kSuper + (kSuper - 1) / 2.0, 0, 0, 1);
    dist_ = cv::Mat(cam.dist, true);
  }
  bool project(const std::vector<Eigen::Vector3d>& pts, std::vector<cv::Point>& out) const {
    std::vector<cv::Point3d> c;
    c.reserve(pts.size());
    for (const auto& p : pts) {
      Eigen::Vector3d q = inv_ * p;
      if (q.z() < 1.0) return false;
      c.emplace_back(q.x(), q.y(), q.z());
    }
    std::vector<cv::Point2d> px;
    cv::projectPoints(c, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), k_, dist_, px);
    out.clear();
    for (const auto& p : px) out.emplace_back(int(std::lround(p.x * (1 << kShift))), int(std::lround(p.y * (1 << kShift))));
    return true;
  }
  void fill(cv::Mat& img, const std::vector<Eigen::Vector3d>& pts, const cv::Scalar& colour) const {
    std::vector<cv::Point> px;
    if (!project(pts, px)) return;
    std::vector<std::vector<cv::Point>> polys{px};
    cv::fillPoly(img, polys, colour, cv::LINE_8, kShift);
  }

 private:
  Eigen::Isometry3d inv_;
  cv::Mat k_, dist_;
};

// The outline at height z with every edge cut into short pieces.
std::vector<Eigen::Vector3d> densify(const Polygon& poly, double z) {
  std::vector<Eigen::Vector3d> out;
  for (size_t i = 0; i < poly.size(); ++i) {
    const auto& a = poly[i];
    const auto& b = poly[(i + 1) % poly.size()];
    int n = std::max(1, int(std::ceil((b - a).norm() / kStepMm)));
    for (int k = 0; k < n; ++k) {
      Eigen::Vector2d p = a + (b - a) * (double(k) / n);
      out.emplace_back(p.x(), p.y(), z);
    }
  }
  return out;
}

Polygon rect(double x, double y, double yaw_deg, double sx, double sy) {
  double c = std::cos(rad(yaw_deg)), s = std::sin(rad(yaw_deg));
  Polygon out;
  for (auto [u, v] : {std::pair{-sx / 2, -sy / 2}, {sx / 2, -sy / 2}, {sx / 2, sy / 2}, {-sx / 2, sy / 2}})
    out.emplace_back(x + c * u - s * v, y + s * u + c * v);
  return out;
}

cv::Scalar bgr(const std::array<double, 3>& c, double f = 1.0) { return cv::Scalar(c[0] * f, c[1] * f, c[2] * f); }

void draw_marker(const Projector& pr, cv::Mat& img, const Marker& m) {
  static const cv::Ptr<cv::aruco::Dictionary> dict = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
  cv::Mat bits;
  cv::aruco::drawMarker(dict, m.id, 6, bits, 1);  // 4x4 bits inside a one-cell black border
  const double cell = m.size_mm / 6.0;
  const double margin = m.size_mm / 6.0;  // white quiet zone around the marker
  pr.fill(img, densify(rect(m.x_mm, m.y_mm, m.yaw_deg, m.size_mm + 2 * margin, m.size_mm + 2 * margin), 0.05),
          cv::Scalar(235, 235, 235));
  double c = std::cos(rad(m.yaw_deg)), s = std::sin(rad(m.yaw_deg));
  for (int r = 0; r < 6; ++r)
    for (int q = 0; q < 6; ++q) {
      // Marker image row r runs along the marker's -y (its image is seen from above, top = +y side).
      double u = (q + 0.5) * cell - m.size_mm / 2, v = m.size_mm / 2 - (r + 0.5) * cell;
      double x = m.x_mm + c * u - s * v, y = m.y_mm + s * u + c * v;
      double shade = bits.at<uchar>(r, q) ? 235 : 25;
      pr.fill(img, densify(rect(x, y, m.yaw_deg, cell * 1.001, cell * 1.001), 0.1), cv::Scalar(shade, shade, shade));
    }
}
}  // namespace

Eigen::Isometry3d camera_pose(const arm::Links& links, const Camera& cam, const arm::Joints& deg) {
  Eigen::Isometry3d mount = Eigen::Isometry3d::Identity();
  mount.linear() = rpy(cam.mount_rpy_deg);
  mount.translation() = Eigen::Vector3d(cam.mount_xyz_mm[0], cam.mount_xyz_mm[1], cam.mount_xyz_mm[2]);
  return arm::fk(links, deg) * mount;
}

Eigen::Vector2d pixel_on_table(const Camera& cam, const Eigen::Isometry3d& pose, double u, double v) {
  Eigen::Vector3d ray = pose.linear() * Eigen::Vector3d((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0);
  Eigen::Vector3d o = pose.translation();
  double t = -o.z() / ray.z();
  return (o + t * ray).head<2>();
}

cv::Mat render_frame(const Scene& scene, const Eigen::Isometry3d& pose, uint64_t frame_index) {
  const Camera& cam = scene.camera;
  const Light& li = scene.light;
  Projector pr(cam, pose);
  cv::Mat img(cam.height * kSuper, cam.width * kSuper, CV_8UC3,
              cv::Scalar(li.table_grey * li.table_tint[0], li.table_grey * li.table_tint[1],
                         li.table_grey * li.table_tint[2]));
  for (const Place& p : scene.places) {
    pr.fill(img, densify(rect(p.x_mm, p.y_mm, p.yaw_deg, p.size_x_mm + 8, p.size_y_mm + 8), p.z_mm), bgr(p.bgr, 0.7));
    pr.fill(img, densify(rect(p.x_mm, p.y_mm, p.yaw_deg, p.size_x_mm, p.size_y_mm), p.z_mm), bgr(p.bgr));
  }
  if (scene.markers_on_table)
    for (const Marker& m : scene.markers) draw_marker(pr, img, m);
  static const std::vector<Object> kNone;
  const std::vector<Object>& objects = objects_on_table(scene) ? scene.objects : kNone;

  // Shadows: each object's footprint swept away from the light to where its top edge's shadow falls.
  cv::Mat shadow(img.size(), CV_8U, cv::Scalar(0));
  const double el = rad(li.shadow_elevation_deg), az = rad(li.shadow_azimuth_deg);
  for (const Object& o : objects) {
    Polygon base = placed_outline(o);
    double reach = o.height_mm / std::tan(el);
    Eigen::Vector2d off(-std::cos(az) * reach, -std::sin(az) * reach);
    Polygon moved = base;
    for (auto& p : moved) p += off;
    for (size_t i = 0; i < base.size(); ++i) {
      size_t k = (i + 1) % base.size();
      Polygon quad{base[i], base[k], moved[k], moved[i]};
      pr.fill(shadow, densify(quad, o.z_mm), cv::Scalar(255));
    }
    pr.fill(shadow, densify(moved, o.z_mm), cv::Scalar(255));
  }
  cv::GaussianBlur(shadow, shadow, cv::Size(), 2.0 * kSuper);
  cv::Mat shade;
  shadow.convertTo(shade, CV_32F, -li.shadow_darkness / 255.0, 1.0);
  cv::Mat f;
  img.convertTo(f, CV_32FC3);
  cv::Mat shade3;
  cv::merge(std::vector<cv::Mat>{shade, shade, shade}, shade3);
  f = f.mul(shade3);
  f.convertTo(img, CV_8UC3);

  // Objects, farthest from the camera first: the sides (darker) then the top face.
  std::vector<const Object*> order;
  for (const Object& o : objects) order.push_back(&o);
  Eigen::Isometry3d inv = pose.inverse();
  std::sort(order.begin(), order.end(), [&inv](const Object* a, const Object* b) {
    return (inv * Eigen::Vector3d(a->x_mm, a->y_mm, a->z_mm)).norm() > (inv * Eigen::Vector3d(b->x_mm, b->y_mm, b->z_mm)).norm();
  });
  for (const Object* o : order) {
    Polygon out = placed_outline(*o);
    double top = o->z_mm + o->height_mm;
    for (size_t i = 0; i < out.size(); ++i) {
      size_t k = (i + 1) % out.size();
      std::vector<Eigen::Vector3d> quad{{out[i].x(), out[i].y(), o->z_mm}, {out[k].x(), out[k].y(), o->z_mm},
                                        {out[k].x(), out[k].y(), top}, {out[i].x(), out[i].y(), top}};
      pr.fill(img, quad, bgr(o->bgr, 0.8));
    }
    pr.fill(img, densify(out, top), bgr(o->bgr));
  }

  cv::Mat small;
  cv::resize(img, small, cv::Size(cam.width, cam.height), 0, 0, cv::INTER_AREA);
  small.convertTo(f, CV_32FC3);
  // Uneven light: a gradient, vignetting, and a drift from frame to frame.
  cv::Mat gain(f.size(), CV_32F);
  const double gd = rad(li.gradient_dir_deg);
  const double half_diag = std::hypot(cam.width / 2.0, cam.height / 2.0);
  const double drift = 1.0 + li.drift * std::sin(0.9 * double(frame_index) + double(scene.seed % 97));
  for (int v = 0; v < f.rows; ++v) {
    float* g = gain.ptr<float>(v);
    for (int u = 0; u < f.cols; ++u) {
      double du = u - cam.width / 2.0, dv = v - cam.height / 2.0;
      double along = (du * std::cos(gd) + dv * std::sin(gd)) / half_diag;  // -1..1
      double r2 = (du * du + dv * dv) / (half_diag * half_diag);
      g[u] = float(drift * (1.0 + li.gradient / 2 * along) * (1.0 - li.vignette * r2));
    }
  }
  cv::Mat gain3;
  cv::merge(std::vector<cv::Mat>{gain, gain, gain}, gain3);
  f = f.mul(gain3);
  if (li.gain != 1.0 || li.offset != 0.0) f.convertTo(f, CV_32FC3, li.gain, li.offset);
  if (li.blur_sigma_px > 0) cv::GaussianBlur(f, f, cv::Size(), li.blur_sigma_px);
  if (li.noise_sigma > 0) {
    cv::RNG rng(scene.seed * 1000003ull + frame_index * 7919ull + 1);
    cv::Mat noise(f.size(), CV_32FC3);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, li.noise_sigma);
    f += noise;
  }
  cv::Mat out;
  f.convertTo(out, CV_8UC3);  // saturates
  return out;
}

}  // namespace rbx1::world
