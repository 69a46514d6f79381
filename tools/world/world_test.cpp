// world_test.cpp - the world's gripper model, geometry, camera and scene file against hand-checked cases.
#include <cmath>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include "camera_view.hpp"
#include "joint_steps.hpp"
#include "kinematics.hpp"
#include "world_state.hpp"

using namespace rbx1::world;

namespace {

// One 30 x 10 mm bar at (300, 0), long axis along base x, 8 mm high; no errors.
Scene bar_scene() {
  Scene s;
  s.links = s.nominal.links;
  s.camera = s.nominal_camera;
  Object o;
  o.id = 1;
  o.cls = "rectangle";
  o.outline = {{-15, -5}, {15, -5}, {15, 5}, {-15, 5}};
  o.grip_yaw_deg = 90;  // the short chord is across the bar
  o.grip_width_mm = 10;
  o.height_mm = 8;
  o.x_mm = 300;
  o.y_mm = 0;
  s.objects.push_back(o);
  Place tray;
  tray.name = "tray";
  tray.x_mm = 150;
  tray.y_mm = 250;
  tray.z_mm = 5;
  tray.size_x_mm = tray.size_y_mm = 120;
  s.places.push_back(tray);
  return s;
}

std::string steps_json(const rbx1::arm::Steps& s) {
  std::string out = "[";
  for (int i = 0; i < 6; ++i) out += (i ? "," : "") + std::to_string(s[i]);
  return out + "]";
}

// Drives a World through log lines built from top-down grasp poses.
struct Driver {
  explicit Driver(World& world) : w(world) {}
  World& w;
  rbx1::arm::ArmConfig cfg;
  rbx1::arm::Steps at = rbx1::arm::joints_to_steps(cfg, cfg.home);
  void move_to(double x, double y, double z, double yaw) {
    rbx1::arm::Joints q;
    std::string e;
    ASSERT_TRUE(rbx1::arm::ik(cfg, {x, y, z, yaw}, rbx1::arm::steps_to_joints(cfg, at), q, e)) << e;
    rbx1::arm::Steps to = rbx1::arm::joints_to_steps(cfg, q);
    std::string line = "{\"kind\":\"move\",\"start\":" + steps_json(at) + ",\"end\":" + steps_json(to) +
                       ",\"target\":" + steps_json(to) + ",\"pulse_us\":0}";
    ASSERT_TRUE(w.apply_log_line(line, e)) << e;
    at = to;
  }
  void gripper(double opening_mm) {
    int pulse = int(std::lround(1000 + 1000 * opening_mm / 50.0));
    std::string e, line = "{\"kind\":\"gripper\",\"start\":" + steps_json(at) + ",\"end\":" + steps_json(at) +
                          ",\"pulse_us\":" + std::to_string(pulse) + "}";
    ASSERT_TRUE(w.apply_log_line(line, e)) << e;
  }
  // Opens to 15 mm 60 mm above (x, y), comes down to 2 mm (the closing line along y) and closes.
  void grasp_at(double x, double y) {
    move_to(x, y, 60, 90);
    gripper(15);
    move_to(x, y, 2, 90);
    gripper(0);
  }
};

int count(const nlohmann::json& state, const char* key) { return state["counts"][key].get<int>(); }

}  // namespace

TEST(Geometry, ExtentInBandAndOverlap) {
  Polygon sq{{0, 0}, {10, 0}, {10, 10}, {0, 10}};
  double lo, hi;
  ASSERT_TRUE(extent_in_band(sq, {5, 5}, {1, 0}, 1.0, lo, hi));
  EXPECT_DOUBLE_EQ(lo, -5);
  EXPECT_DOUBLE_EQ(hi, 5);
  EXPECT_FALSE(extent_in_band(sq, {5, 20}, {1, 0}, 2.0, lo, hi));  // the band passes 8 mm beside it
  Polygon l{{0, 0}, {30, 0}, {30, 8}, {8, 8}, {8, 20}, {0, 20}};   // an L: its band at y = 15 is only the stem
  ASSERT_TRUE(extent_in_band(l, {0, 15}, {1, 0}, 1.0, lo, hi));
  EXPECT_NEAR(lo, 0, 1e-9);
  EXPECT_NEAR(hi, 8, 1e-9);
  EXPECT_TRUE(polygons_overlap(sq, {{9, 9}, {20, 9}, {20, 20}, {9, 20}}));
  EXPECT_FALSE(polygons_overlap(sq, {{11, 0}, {20, 0}, {20, 10}, {11, 10}}));
  EXPECT_TRUE(polygons_overlap(sq, {{-5, 4}, {15, 4}, {15, 6}, {-5, 6}}));  // crossing, no vertex inside
}

TEST(Gripper, StraddlingGraspCarriesTheObjectToTheTray) {
  World w(bar_scene());
  Driver d(w);
  // Over the 10 mm bar, the closing line across it, opened to 15 mm.
  d.grasp_at(300, 0);
  auto s = w.state();
  EXPECT_EQ(count(s, "collisions"), 0);
  ASSERT_EQ(count(s, "grasps"), 1);
  EXPECT_EQ(s["arm"]["holding"], 1);
  EXPECT_NEAR(s["arm"]["opening_mm"].get<double>(), 10.0, 0.05);
  const auto& g = s["events"].back();
  EXPECT_EQ(g["event"], "grasp");
  EXPECT_LT(g["offset_mm"].get<double>(), 0.2);
  EXPECT_LT(g["yaw_error_deg"].get<double>(), 0.1);
  d.move_to(300, 0, 80, 90);
  d.move_to(150, 250, 80, 0);
  d.gripper(15);
  s = w.state();
  EXPECT_EQ(count(s, "placements"), 1);
  EXPECT_EQ(s["objects"][0]["place"], "tray");
  EXPECT_NEAR(s["objects"][0]["x_mm"].get<double>(), 150, 0.3);
  EXPECT_NEAR(s["objects"][0]["y_mm"].get<double>(), 250, 0.3);
  EXPECT_DOUBLE_EQ(s["objects"][0]["z_mm"].get<double>(), 5.0);
  EXPECT_EQ(s["arm"]["holding"], nullptr);
}

TEST(Gripper, OffCentreGraspIsCentredAndReported) {
  World w(bar_scene());
  Driver d(w);
  d.move_to(306, 2, 60, 90);  // 6 mm along the bar, 2 mm across: still straddles it
  d.gripper(20);
  d.move_to(306, 2, 2, 90);
  d.gripper(0);
  auto s = w.state();
  ASSERT_EQ(count(s, "grasps"), 1);
  EXPECT_NEAR(s["events"].back()["offset_mm"].get<double>(), std::hypot(6.0, 2.0), 0.1);
  // The fingers pushed the bar across until it sat centred between them.
  EXPECT_NEAR(s["objects"][0]["y_mm"].get<double>(), 2.0, 0.15);
}

TEST(Gripper, DescendingOntoTheObjectIsACollision) {
  World w(bar_scene());
  Driver d(w);
  d.move_to(300, 8, 60, 90);  // 8 mm off across a 10 mm bar: a 15 mm opening puts a finger on it
  d.gripper(15);
  d.move_to(300, 8, 2, 90);
  auto s = w.state();
  ASSERT_EQ(count(s, "collisions"), 1);
  EXPECT_EQ(s["events"].back()["event"], "collision");
  EXPECT_EQ(s["events"].back()["object"], 1);
  d.gripper(0);
  s = w.state();
  EXPECT_EQ(count(s, "grasps"), 0);
  EXPECT_EQ(count(s, "closed_empty"), 1);
  EXPECT_EQ(s["events"].back()["reason"], "a finger is on object 1");
}

TEST(Gripper, ClosingBesideTheObjectClosesOnNothing) {
  World w(bar_scene());
  Driver d(w);
  d.grasp_at(300, 30);
  auto s = w.state();
  EXPECT_EQ(count(s, "collisions"), 0);
  EXPECT_EQ(count(s, "grasps"), 0);
  EXPECT_EQ(count(s, "closed_empty"), 1);
  EXPECT_EQ(s["events"].back()["reason"], "nothing between the fingers");
  EXPECT_DOUBLE_EQ(s["objects"][0]["moved_mm"].get<double>(), 0.0);
}

TEST(Gripper, AboveTheObjectNothingHappens) {
  World w(bar_scene());
  Driver d(w);
  d.move_to(300, 0, 60, 0);
  d.gripper(5);
  d.move_to(300, 0, 9, 0);  // fingertips 1 mm above the 8 mm top, closing line along the bar
  d.gripper(0);
  auto s = w.state();
  EXPECT_EQ(count(s, "collisions"), 0);
  EXPECT_EQ(count(s, "grasps"), 0);
}

TEST(Gripper, FingertipsBelowTheTableAreACollision) {
  World w(bar_scene());
  Driver d(w);
  d.move_to(350, 50, 60, 0);
  d.move_to(350, 50, -1, 0);
  auto s = w.state();
  ASSERT_EQ(count(s, "collisions"), 1);
  EXPECT_EQ(s["events"].back()["class"], "table");
  EXPECT_EQ(s["events"].back()["object"], nullptr);
}

TEST(Camera, NominalScanViewMatchesTheDaemonsMapping) {
  // data/rbx1.toml [arm.camera]: pixel (0, 0) at (370, 100) mm, image x = base -y, 40 px/cm.
  Scene s = bar_scene();
  auto pose = camera_pose(s.links, s.camera, s.nominal.scan);
  Eigen::Vector2d o = pixel_on_table(s.camera, pose, 0, 0);
  EXPECT_NEAR(o.x(), 370.0, 0.01);
  EXPECT_NEAR(o.y(), 100.0, 0.01);
  Eigen::Vector2d e = pixel_on_table(s.camera, pose, 400, 0);
  EXPECT_NEAR(e.x(), 370.0, 0.01);
  EXPECT_NEAR(e.y(), 0.0, 0.01);
}

TEST(Camera, TheBarIsDarkWhereTheMappingPutsIt) {
  Scene s = bar_scene();
  s.objects[0].bgr = {40, 40, 40};
  s.light.noise_sigma = 0;
  auto pose = camera_pose(s.links, s.camera, s.nominal.scan);
  cv::Mat img = render_frame(s, pose, 0);
  ASSERT_EQ(img.cols, 800);
  ASSERT_EQ(img.rows, 600);
  cv::Mat grey, mask;
  cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  cv::threshold(grey, mask, 110, 255, cv::THRESH_BINARY_INV);
  cv::Moments m = cv::moments(mask, true);
  ASSERT_GT(m.m00, 100);
  // (300, 0) mm -> pixel ((100 - 0) * 4, (370 - 300) * 4) = (400, 280); the top face 8 mm nearer the camera
  // is magnified about the optical axis (pixel 399.5, 299.5) by 488 / 480.
  double k = 488.0 / 480.0;
  EXPECT_NEAR(m.m10 / m.m00, 399.5 + (400 - 399.5) * k, 0.5);
  EXPECT_NEAR(m.m01 / m.m00, 299.5 + (280 - 299.5) * k, 0.5);
  // 30 mm along base x = 120 px along image y; 10 mm across = 40 px (top face, magnified).
  EXPECT_NEAR(std::sqrt(m.mu02 / m.m00 * 12), 120 * k, 3);
  EXPECT_NEAR(std::sqrt(m.mu20 / m.m00 * 12), 40 * k, 3);
}

TEST(Table, TheMarkerSheetSetsTheObjectsAsideAndIsSeenWhereItLies) {
  Scene s = bar_scene();
  s.light.noise_sigma = 0;
  Marker m;
  m.id = 7;
  m.x_mm = 320;
  m.y_mm = -40;
  m.size_mm = 24;
  s.markers.push_back(m);
  World w(s);
  std::string e;
  ASSERT_TRUE(w.set_markers_on_table(true, e)) << e;
  // The camera sees the marker, not the bar: (320, -40) mm -> pixel ((100 + 40) * 4, (370 - 320) * 4).
  auto pose = camera_pose(s.links, s.camera, s.nominal.scan);
  cv::Mat img = render_frame(w.scene(), pose, 0);
  std::vector<int> ids;
  std::vector<std::vector<cv::Point2f>> corners;
  cv::aruco::detectMarkers(img, cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50), corners, ids);
  ASSERT_EQ(ids, std::vector<int>{7});
  cv::Point2f c = (corners[0][0] + corners[0][1] + corners[0][2] + corners[0][3]) / 4;
  EXPECT_NEAR(c.x, 560, 1.0);
  EXPECT_NEAR(c.y, 200, 1.0);
  cv::Mat grey;
  cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  EXPECT_GT(grey.at<uchar>(280, 400), 150) << "the bar is set aside";
  // Fingers coming down where the bar was touch nothing; closing there grasps nothing.
  Driver d(w);
  d.grasp_at(300, 0);
  auto st = w.state();
  EXPECT_EQ(count(st, "collisions"), 0);
  EXPECT_EQ(count(st, "grasps"), 0);
  EXPECT_TRUE(st["markers_on_table"].get<bool>());
  // The sheet taken away: the bar is back and grasped.
  ASSERT_TRUE(w.set_markers_on_table(false, e)) << e;
  d.gripper(15);
  d.gripper(0);
  st = w.state();
  EXPECT_EQ(count(st, "grasps"), 1);
  EXPECT_FALSE(w.set_markers_on_table(true, e));
  EXPECT_NE(e.find("holds object 1"), std::string::npos) << e;
}

TEST(Table, ClearedTheCameraSeesTheEmptyTableAndTheLightChangesItsLevels) {
  Scene s = bar_scene();
  s.light.noise_sigma = 0;
  s.light.blur_sigma_px = 0;
  World w(s);
  auto pose = camera_pose(s.links, s.camera, s.nominal.scan);
  auto grey_at = [&](int v, int u) {
    cv::Mat g;
    cv::cvtColor(render_frame(w.scene(), pose, 0), g, cv::COLOR_BGR2GRAY);
    return double(g.at<uchar>(v, u));
  };
  // Pixel (280, 400) lies on the bar, (100, 100) on the table.
  const double bar = grey_at(280, 400), table = grey_at(100, 100);
  ASSERT_LT(bar, 100);
  std::string e;
  ASSERT_TRUE(w.set_table_cleared(true, e)) << e;
  EXPECT_NEAR(grey_at(280, 400), grey_at(300, 430), 3) << "the bar set aside: table there";
  EXPECT_GT(grey_at(280, 400), 150);
  Driver d(w);
  d.grasp_at(300, 0);
  EXPECT_EQ(count(w.state(), "grasps"), 0) << "nothing to close on";
  EXPECT_TRUE(w.state()["table_cleared"].get<bool>());
  // The objects back; the light at 0.8 with the black level 10 down: every level = level * 0.8 - 10 (+-1
  // for the rounding of two 8-bit conversions).
  ASSERT_TRUE(w.set_table_cleared(false, e)) << e;
  ASSERT_TRUE(w.set_light(0.8, -10, e)) << e;
  EXPECT_NEAR(grey_at(100, 100), table * 0.8 - 10, 1.0);
  EXPECT_NEAR(grey_at(280, 400), bar * 0.8 - 10, 1.0);
  EXPECT_EQ(w.state()["light"]["gain"].get<double>(), 0.8);
  ASSERT_TRUE(w.set_light(1.2, 10, e)) << e;
  EXPECT_NEAR(grey_at(100, 100), std::min(255.0, table * 1.2 + 10), 1.0);
  EXPECT_FALSE(w.set_light(0.1, 0, e));
  EXPECT_NE(e.find("gain within"), std::string::npos) << e;
  EXPECT_FALSE(w.set_light(1.0, 150, e));
  // Holding an object, the table cannot be cleared.
  ASSERT_TRUE(w.set_light(1.0, 0, e)) << e;
  d.gripper(15);
  d.gripper(0);
  ASSERT_EQ(count(w.state(), "grasps"), 1);
  EXPECT_FALSE(w.set_table_cleared(true, e));
  EXPECT_NE(e.find("holds object 1"), std::string::npos) << e;
}

TEST(Scene, ErrorsAreDrawnFromTheSeedWithinTheirMagnitudes) {
  const std::string path = testing::TempDir() + "world_scene_test.json";
  std::ofstream(path) << R"({"format": "rbx1-world", "version": 1, "seed": 5,
    "errors": {"links_mm": 1, "mount_mm": 5, "mount_deg": 3},
    "objects": [{"class": "rectangle", "outline_mm": [[-5, -5], [5, -5], [5, 5]], "grip_yaw_deg": 0,
                 "grip_width_mm": 10, "x_mm": 300, "y_mm": 0}]})";
  Scene a, b, c;
  std::string e;
  ASSERT_TRUE(load_scene(path, a, e)) << e;
  ASSERT_TRUE(load_scene(path, b, e)) << e;
  ASSERT_TRUE(load_scene(path, c, e, 6)) << e;
  EXPECT_EQ(a.errors.mount_rpy_drawn, b.errors.mount_rpy_drawn);
  EXPECT_NE(a.errors.mount_rpy_drawn, c.errors.mount_rpy_drawn);
  for (double v : a.errors.links_drawn) EXPECT_LE(std::abs(v), 1.0);
  for (double v : a.errors.mount_xyz_drawn) EXPECT_LE(std::abs(v), 5.0);
  for (double v : a.errors.mount_rpy_drawn) EXPECT_LE(std::abs(v), 3.0);
  EXPECT_NEAR(a.links.tool_mm - a.nominal.links.tool_mm, a.errors.links_drawn[3], 1e-12);
}

TEST(Scene, BadFilesAreOneLineNamingTheField) {
  const std::string path = testing::TempDir() + "world_scene_bad.json";
  auto expect = [&path](const std::string& text, const std::string& message) {
    std::ofstream(path, std::ios::trunc) << text;
    Scene s;
    std::string e;
    EXPECT_FALSE(load_scene(path, s, e));
    EXPECT_EQ(e, path + ": " + message);
  };
  expect(R"({"format": "x", "version": 1})", "format: must be \"rbx1-world\"");
  expect(R"({"format": "rbx1-world", "version": 1})", "objects: missing (an array)");
  expect(R"({"format": "rbx1-world", "version": 1, "objects": [{"class": "a", "outline_mm": [[0, 0], [1, 0]]}]})",
         "objects[0].outline_mm: missing (at least 3 points)");
  expect(R"({"format": "rbx1-world", "version": 1, "objects": [{"class": "a", "outline_mm": [[0, 0], [1, 0], [1, 1]],
            "grip_yaw_deg": 0, "grip_width_mm": 1, "x_mm": 300}]})", "objects[0].y_mm: missing");
  expect(R"({"format": "rbx1-world", "version": 1, "light": {"noise_sigma": "a"}, "objects": []})",
         "light.noise_sigma: must be a number");
  Scene s;
  std::string e;
  EXPECT_FALSE(load_scene(path + ".absent", s, e));
  EXPECT_EQ(e, path + ".absent: cannot read the scene file");
}
