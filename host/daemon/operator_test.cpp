// operator_test.cpp - the operator commands' request parsing (every field checked) and the state directory (files
// applied over the config, atomic saves, corrupt files named and left alone).
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "request.hpp"
#include "state_dir.hpp"

namespace fs = std::filesystem;
using namespace rbx1::daemon;

namespace {

Request parse_ok(const std::string& line) {
  Request r;
  Error e;
  EXPECT_TRUE(parse_request(line, r, e)) << line << ": " << e.code << " " << e.message;
  // The client writes what the daemon reads.
  Request back;
  EXPECT_TRUE(parse_request(request_json(r).dump(), back, e)) << request_json(r).dump();
  EXPECT_EQ(request_json(back), request_json(r));
  return r;
}

std::string parse_error(const std::string& line) {
  Request r;
  Error e;
  EXPECT_FALSE(parse_request(line, r, e)) << line;
  return e.code;
}

struct TempDir {
  fs::path path = fs::temp_directory_path() / ("rbx1_operator_test_" + std::to_string(::getpid()));
  TempDir() { fs::remove_all(path); }
  ~TempDir() { fs::remove_all(path); }
};

}  // namespace

TEST(OperatorRequest, JogForms) {
  Request r = parse_ok(R"({"cmd":"jog","joint":2,"steps":-100})");
  EXPECT_EQ(r.command, Command::Jog);
  EXPECT_EQ(r.joint, 2);
  EXPECT_TRUE(r.by_steps);
  EXPECT_EQ(r.steps, -100);
  r = parse_ok(R"({"cmd":"jog","joint":6,"deg":1.5})");
  EXPECT_FALSE(r.by_steps);
  EXPECT_DOUBLE_EQ(r.deg, 1.5);
  r = parse_ok(R"({"cmd":"jog","mm":[1,-2.5,3]})");
  EXPECT_EQ(r.joint, 0);
  EXPECT_DOUBLE_EQ(r.mm[1], -2.5);
  EXPECT_EQ(parse_error(R"({"cmd":"jog"})"), "missing_field");
  EXPECT_EQ(parse_error(R"({"cmd":"jog","joint":0,"steps":1})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"jog","joint":7,"steps":1})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"jog","joint":1,"steps":1.5})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"jog","joint":1,"steps":1,"deg":1})"), "bad_request");
  EXPECT_EQ(parse_error(R"({"cmd":"jog","joint":1})"), "bad_request");
  EXPECT_EQ(parse_error(R"({"cmd":"jog","joint":1,"deg":"1"})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"jog","joint":1,"deg":361})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"jog","mm":[1,2]})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"jog","mm":[1,2,"x"]})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"jog","mm":[1,2,3],"joint":1})"), "bad_request");
  EXPECT_EQ(parse_error(R"({"cmd":"jog","mm":[1,2,3],"speed":1})"), "bad_field");
}

TEST(OperatorRequest, SavesTeachBackground) {
  EXPECT_EQ(parse_ok(R"({"cmd":"pose_save","name":"scan"})").command, Command::PoseSave);
  EXPECT_EQ(parse_error(R"({"cmd":"pose_save","name":"home"})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"pose_save"})"), "missing_field");
  EXPECT_EQ(parse_ok(R"({"cmd":"place_save","name":"bin 2"})").name, "bin 2");
  EXPECT_EQ(parse_error(R"({"cmd":"place_save","name":""})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"place_save","name":"a\u0001"})"), "bad_field");
  EXPECT_EQ(parse_ok(R"({"cmd":"background"})").frames, 0);
  EXPECT_EQ(parse_ok(R"({"cmd":"background","frames":16})").frames, 16);
  EXPECT_EQ(parse_error(R"({"cmd":"background","frames":0})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"background","frames":65})"), "bad_field");
  Request t = parse_ok(R"({"cmd":"teach","index":3,"name":"bolt","mirror_ok":true})");
  EXPECT_EQ(t.index, 3);
  EXPECT_TRUE(t.mirror_ok);
  EXPECT_EQ(parse_error(R"({"cmd":"teach","name":"bolt"})"), "missing_field");
  EXPECT_EQ(parse_error(R"({"cmd":"teach","index":0,"name":"bolt"})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"teach","index":1,"name":"bolt","mirror_ok":1})"), "bad_field");
}

TEST(OperatorRequest, CalibrateWorkspaceActions) {
  for (const char* a : {"start", "status", "fit", "save", "cancel"})
    EXPECT_EQ(parse_ok(std::string(R"({"cmd":"calibrate_workspace","action":")") + a + "\"}").action, a);
  Request r = parse_ok(R"({"cmd":"calibrate_workspace","action":"record","marker":7})");
  EXPECT_EQ(r.index, 7);
  EXPECT_EQ(parse_error(R"({"cmd":"calibrate_workspace"})"), "missing_field");
  EXPECT_EQ(parse_error(R"({"cmd":"calibrate_workspace","action":"go"})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"calibrate_workspace","action":"record"})"), "missing_field");
  EXPECT_EQ(parse_error(R"({"cmd":"calibrate_workspace","action":"fit","marker":1})"), "bad_field");
  EXPECT_EQ(parse_error(R"({"cmd":"calibrate_workspace","action":"record","marker":-1})"), "bad_field");
}

TEST(StateDir, AppliesSavedDataOverTheConfig) {
  TempDir t;
  StateDir s(t.path.string());
  Config c;
  c.arm = rbx1::arm::default_arm_config();
  c.vision.library_path = "/etc/lib.json";
  std::string error;
  // Nothing saved: nothing changes (and the folder is not created by reading).
  Config before = c;
  ASSERT_TRUE(s.apply(c, error)) << error;
  EXPECT_EQ(c.arm, before.arm);
  EXPECT_FALSE(fs::exists(t.path));
  rbx1::arm::Joints scan{5, 25, 55, 0, 100, 3};
  ASSERT_TRUE(s.save_scan_pose(scan, error)) << error;
  ASSERT_TRUE(s.save_place("bin", {100, -200, 15, 30}, error)) << error;
  ASSERT_TRUE(s.save_place("tray", {1, 2, 3, 4}, error)) << error;
  ASSERT_TRUE(s.save_background(cv::Mat(4, 6, CV_8UC3, cv::Scalar(9, 9, 9)), error)) << error;
  ASSERT_TRUE(s.apply(c, error)) << error;
  EXPECT_EQ(c.arm.scan, scan);
  EXPECT_EQ(c.arm.places.at("bin"), (rbx1::arm::Place{100, -200, 15, 30}));
  EXPECT_EQ(c.arm.places.at("tray"), (rbx1::arm::Place{1, 2, 3, 4}));  // replaced by name
  EXPECT_EQ(c.vision.background_path, s.path(kBackgroundFile));
  EXPECT_EQ(c.vision.library_path, "/etc/lib.json");  // none taught: the configured one stays
  EXPECT_EQ(cv::imread(s.path(kBackgroundFile)).cols, 6);
  EXPECT_FALSE(c.arm.camera.pixel_map);
  // No temporary files left behind.
  for (const auto& e : fs::directory_iterator(t.path))
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
}

TEST(StateDir, CorruptFilesAreNamedAndLeftAlone) {
  TempDir t;
  StateDir s(t.path.string());
  std::string error;
  ASSERT_TRUE(s.ensure(error));
  Config c;
  c.arm = rbx1::arm::default_arm_config();
  const std::pair<const char*, const char*> bad[] = {
      {kPosesFile, "{"},
      {kPosesFile, R"({"scan": [1, 2, 3]})"},
      {kPosesFile, R"({"scan": [0, 0, 0, 0, 200, 0]})"},  // J5 beyond its limit
      {kPlacesFile, R"({"bin": {"x_mm": 1}})"},
      {kPlacesFile, "[]"},
      {kWorkspaceFile, R"({"format": "rbx1-workspace", "version": 9})"},
  };
  for (const auto& [file, text] : bad) {
    fs::remove_all(t.path);
    ASSERT_TRUE(s.ensure(error));
    std::ofstream(s.path(file)) << text;
    Config keep = c;
    EXPECT_FALSE(s.apply(keep, error)) << file << " " << text;
    EXPECT_EQ(error.rfind(s.path(file) + ": ", 0), 0u) << error;
    std::ifstream in(s.path(file));
    std::string back((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(back, text);
    // A save over an unreadable file is refused too: what the operator taught is never dropped silently.
    if (std::string(file) == kPlacesFile && text[0] == '[') {
      EXPECT_FALSE(s.save_place("x", {}, error));
    }
  }
}
