// world_state.hpp - the world as it runs: the arm's true pose from the firmware's executed queue entries, the
// gripper acting on the objects (grasp, collision, release), the event log, and the state as JSON.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "scene.hpp"

namespace rbx1::world {

class World {
 public:
  explicit World(Scene scene);

  // One line of rbx1-simfw's move log (firmware/README.md): a move is swept from start to end (collisions, the
  // held object follows), a gripper entry opens or closes the fingers at the entry's position.
  // false + error for a line that is not such an entry.
  bool apply_log_line(const std::string& line, std::string& error);

  // The operator lays the marker sheet on the table for a workspace calibration (the objects set aside: neither
  // seen nor touched) or takes it away (the objects back where they were). false + error while holding an object.
  bool set_markers_on_table(bool on, std::string& error);

  // The operator clears the table (the objects set aside, nothing laid there: the empty table for `rbx1
  // background`) or puts the objects back. false + error while holding an object.
  bool set_table_cleared(bool cleared, std::string& error);

  // The light changes to a steady gain and black-level offset (Light::gain, offset; the light sweep's levels).
  // false + error outside kMinGain..kMaxGain, +-kMaxOffset.
  bool set_light(double gain, double offset, std::string& error);

  // Every event (grasp, closed_empty, collision, placement, dropped) goes here as it happens.
  void on_event(std::function<void(const nlohmann::json&)> f) { on_event_ = std::move(f); }

  const Scene& scene() const { return scene_; }
  const arm::Joints& joints() const { return joints_; }
  double opening_mm() const { return opening_mm_; }
  nlohmann::json state() const;  // the whole state: errors drawn, arm, gripper, objects, counts, events

 private:
  struct Held {
    int index = -1;             // into scene_.objects
    Eigen::Isometry3d in_tool;  // the object's bottom-centre frame in the tool frame
  };
  // Whether the table may change: not while the gripper holds an object (error says which).
  bool table_free(std::string& error) const;
  void at_pose(const arm::Joints& deg, bool final_sample, std::vector<int>& hit);
  void gripper_to(double opening);
  void emit(nlohmann::json ev);
  Eigen::Isometry3d tool(const arm::Joints& deg) const;

  Scene scene_;
  std::vector<Object> initial_;
  arm::Joints joints_{};
  double opening_mm_ = 0;
  Held held_;
  uint64_t entries_ = 0;
  uint64_t sim_ms_ = 0;  // the executed entries' planned durations (simulated time)
  int grasps_ = 0, closed_empty_ = 0, collisions_ = 0, placements_ = 0;
  std::vector<nlohmann::json> events_;
  std::function<void(const nlohmann::json&)> on_event_;
};

// Geometry used by the gripper model (exposed for the tests).
bool point_in_polygon(const Eigen::Vector2d& p, const Polygon& poly);
bool polygons_overlap(const Polygon& a, const Polygon& b);
// The polygon's extent along unit direction u, over its part within |(p - c) . v| <= half_width (v = u rotated
// 90 deg), as [lo, hi] measured from c; false when no part of the polygon is within the band.
bool extent_in_band(const Polygon& poly, const Eigen::Vector2d& c, const Eigen::Vector2d& u, double half_width,
                    double& lo, double& hi);

}  // namespace rbx1::world
