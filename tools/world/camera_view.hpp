// camera_view.hpp - the virtual camera on the end effector: its pose from the true arm, and the frame it sees.
#pragma once
#include <cstdint>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "scene.hpp"

namespace rbx1::world {

// The camera frame (OpenCV: x right, y down in the image, z along the view) in the base frame, mm.
Eigen::Isometry3d camera_pose(const arm::Links& links, const Camera& cam, const arm::Joints& deg);

// Renders what the camera sees from `pose`: table with uneven light, places, markers, shadows, objects (sides
// and tops, through the lens' distortion), then blur and sensor noise. `frame_index` drives the light drift and
// seeds the noise with the scene's seed, so a frame is a function of (scene, pose, index).
cv::Mat render_frame(const Scene& scene, const Eigen::Isometry3d& pose, uint64_t frame_index);

// The table point (z = 0) that pixel (u, v) of the nominal camera sees at the given pose (no lens distortion).
Eigen::Vector2d pixel_on_table(const Camera& cam, const Eigen::Isometry3d& pose, double u, double v);

}  // namespace rbx1::world
