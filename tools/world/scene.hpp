// scene.hpp - the world's scene file: table, light, objects, places, markers, the true arm and camera, the errors.
#pragma once
#include <array>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "arm_config.hpp"

namespace rbx1::world {

using Polygon = std::vector<Eigen::Vector2d>;  // a closed outline in mm, counter-clockwise or not

struct Object {
  int id = 0;
  std::string cls;              // the scene generator's class (the daemon's library label)
  Polygon outline;              // about the object's area centroid, in the base frame's axes at yaw 0
  double grip_yaw_deg = 0;      // the true grip's closing direction at yaw 0 (shortest chord through the centroid)
  double grip_width_mm = 0;     // that chord's length
  double height_mm = 10;
  std::array<double, 3> bgr{60, 60, 60};
  // The pose (changes as the world runs): centroid, rotation about z, bottom height.
  double x_mm = 0, y_mm = 0, yaw_deg = 0, z_mm = 0;
};

struct Place {
  std::string name;
  double x_mm = 0, y_mm = 0, z_mm = 0, yaw_deg = 0;  // centre, floor height, gripper yaw at release
  double size_x_mm = 100, size_y_mm = 100;
  std::array<double, 3> bgr{120, 150, 170};
};

struct Marker {
  int id = 0;  // ArUco DICT_4X4_50
  double x_mm = 0, y_mm = 0, yaw_deg = 0, size_mm = 30;
};

struct Camera {
  int width = 800, height = 600;
  double fx = 1952, fy = 1952, cx = 399.5, cy = 299.5;
  std::vector<double> dist{0, 0, 0, 0, 0};  // k1 k2 p1 p2 k3 (OpenCV)
  // The mount in the tool frame: translation (mm) and rotation Rz(yaw) Ry(pitch) Rx(roll) (deg).
  std::array<double, 3> mount_xyz_mm{-7.804, 0.125, -100.0};
  std::array<double, 3> mount_rpy_deg{0.0, 0.0, -90.0};
};

// The range of the steady light change (Light::gain, offset) a scene or the "light" request may set.
constexpr double kMinGain = 0.2, kMaxGain = 3.0, kMaxOffset = 100.0;

struct Light {
  int table_grey = 190;
  std::array<double, 3> table_tint{1.0, 1.0, 1.0};
  double gradient = 0.08;       // brightness change across the image
  double gradient_dir_deg = 30;
  double vignette = 0.08;       // darkening at the corners
  double drift = 0.0;           // brightness swing from frame to frame (fraction)
  // A steady change of the light after the scene was set up (the light sweep's levels, issue 27): each frame
  // is frame * gain + offset before the sensor's noise (a brighter or dimmer lamp, a raised black level).
  double gain = 1.0, offset = 0.0;
  double shadow_darkness = 0.15;
  double shadow_azimuth_deg = 135;  // where the light comes from, in the base frame
  double shadow_elevation_deg = 60;
  double noise_sigma = 1.5;
  double blur_sigma_px = 0.7;
};

struct Gripper {
  int closed_us = 1000, open_us = 2000;
  double max_opening_mm = 50;
  double finger_width_mm = 10;      // across the closing line
  double finger_thickness_mm = 8;   // outward from the inner face
  double finger_length_mm = 15;     // up from the fingertips
};

// Magnitudes of the errors drawn (uniformly within +-) from the seed, and the values drawn.
struct Errors {
  double links_mm = 0, mount_mm = 0, mount_deg = 0;
  std::array<double, 4> links_drawn{};
  std::array<double, 3> mount_xyz_drawn{}, mount_rpy_drawn{};
};

struct Scene {
  uint64_t seed = 1;
  Light light;
  arm::ArmConfig nominal;  // the links and the joints' step conversion the world's arm is built to
  arm::Links links;        // the true links = nominal + drawn errors
  Camera nominal_camera;
  Camera camera;           // the true camera = nominal mount + drawn errors (the lens is the same)
  Gripper gripper;
  Errors errors;
  std::vector<Object> objects;
  std::vector<Place> places;
  std::vector<Marker> markers;
  // What lies on the table: the marker sheet (the objects set aside, neither seen nor touched) or the objects.
  bool markers_on_table = false;
  // The objects set aside and nothing laid on the table: the empty table an operator shows `rbx1 background`.
  bool table_cleared = false;
};

// The objects lie on the table (seen and touched): neither the marker sheet nor a cleared table.
inline bool objects_on_table(const Scene& s) { return !s.markers_on_table && !s.table_cleared; }

// Loads and checks a scene file; false + "PATH: reason" (naming the field). Draws the errors from the seed.
bool load_scene(const std::string& path, Scene& out, std::string& error, std::optional<uint64_t> seed = {});

// The place whose rectangle holds (x, y), or null.
const Place* place_at(const Scene& s, double x_mm, double y_mm);

// The outline of an object at its current pose, in base-frame mm.
Polygon placed_outline(const Object& o);

}  // namespace rbx1::world
