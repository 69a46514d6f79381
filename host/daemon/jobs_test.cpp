// jobs_test.cpp - the cell jobs' parts without an arm: recipes (checks naming the offender, "*" and "unknown",
// the recipes file), the choice of the next object from a scan's structs (skip reasons, the same object, ranking),
// the requests' fields.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "command_table.hpp"
#include "kinematics.hpp"
#include "pick_plan.hpp"
#include "vision_map.hpp"
#include "recipes.hpp"
#include "request.hpp"
#include "sort_choice.hpp"

namespace fs = std::filesystem;
using namespace rbx1::daemon;
using nlohmann::json;

namespace {

const std::set<std::string> kPlaces{"tray", "bin", "reject"};
const std::set<std::string> kClasses{"bolt", "nut", "washer"};

using rbx1::vision::GripReason;

rbx1::vision::ScanObject object(int index, std::optional<std::string> label, double x, double y, bool feasible = true,
                                GripReason reason = GripReason::None, bool touching = false) {
  rbx1::vision::ScanObject o;
  o.index = index;
  o.identity = {label, label ? std::optional(0.9) : std::nullopt};
  o.centroid_cm = cv::Point2d(x, y);
  o.touching = touching;
  o.grip.opening_cm = 1.0;
  o.grip.angle_deg = 10.0;
  o.grip.feasible = feasible;
  o.grip.reason = reason;
  return o;
}

std::string read_all(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

}  // namespace

TEST(Recipe, CheckNamesAnUnknownPlaceOrClass) {
  std::string error;
  Recipe ok{{"bolt", "tray"}, {"*", "bin"}, {"unknown", "reject"}};
  EXPECT_TRUE(check_recipe(ok, kPlaces, kClasses, error)) << error;
  EXPECT_FALSE(check_recipe({{"bolt", "shelf"}}, kPlaces, kClasses, error));
  EXPECT_EQ(error, "recipe: bolt -> no place \"shelf\" in [arm] places (known: bin, reject, tray)");
  EXPECT_FALSE(check_recipe({{"screw", "tray"}}, kPlaces, kClasses, error));
  EXPECT_EQ(error, "recipe: the library knows no class \"screw\" (known: bolt, nut, washer, and \"*\", \"unknown\")");
}

TEST(Recipe, PlaceForUsesItsOwnKeyThenStarForIdentifiedOnly) {
  Recipe r{{"bolt", "tray"}, {"*", "bin"}};
  EXPECT_EQ(place_for(r, "bolt"), "tray");
  EXPECT_EQ(place_for(r, "nut"), "bin");
  EXPECT_EQ(place_for(r, std::nullopt), std::nullopt);  // "*" is every identified class, not the unknown ones
  r["unknown"] = "reject";
  EXPECT_EQ(place_for(r, std::nullopt), "reject");
  EXPECT_EQ(place_for({{"bolt", "tray"}}, "nut"), std::nullopt);  // left on the table
}

TEST(Recipe, FromJsonRefusesWhatIsNotAMapOfNames) {
  Recipe r;
  std::string error;
  EXPECT_TRUE(recipe_from_json({{"bolt", "tray"}}, r, error));
  EXPECT_FALSE(recipe_from_json(json::object(), r, error));
  EXPECT_FALSE(recipe_from_json({{"bolt", 3}}, r, error));
  EXPECT_FALSE(recipe_from_json(json::array(), r, error));
}

TEST(RecipeBook, SavesAtomicallyFindsByNameAndLeavesACorruptFileAlone) {
  char tmpl[] = "/tmp/rbx1-recipes-XXXXXX";
  fs::path dir = mkdtemp(tmpl);
  RecipeBook book(dir.string());
  std::string error;
  Recipe r;
  EXPECT_FALSE(book.find("bins", r, error));
  EXPECT_NE(error.find("no recipe \"bins\""), std::string::npos) << error;
  ASSERT_TRUE(book.save("bins", {{"bolt", "tray"}, {"*", "bin"}}, error)) << error;
  ASSERT_TRUE(book.save("all", {{"*", "bin"}}, error)) << error;
  ASSERT_TRUE(book.find("bins", r, error)) << error;
  EXPECT_EQ(r.at("bolt"), "tray");
  EXPECT_EQ(json::parse(read_all(dir / "recipes.json"))["all"]["*"], "bin");
  int files = 0;
  for (auto it = fs::directory_iterator(dir); it != fs::directory_iterator(); ++it) ++files;
  EXPECT_EQ(files, 1);  // no temp file left behind
  std::ofstream(dir / "recipes.json") << "{not json";
  EXPECT_FALSE(book.save("more", {{"*", "bin"}}, error));
  EXPECT_NE(error.find((dir / "recipes.json").string() + ": not a JSON object"), std::string::npos) << error;
  EXPECT_EQ(read_all(dir / "recipes.json"), "{not json");
  fs::remove_all(dir);
}

TEST(SortChoice, SkipsWithReasonsAndLeavesUnmappedClasses) {
  rbx1::vision::Scan det;
  det.objects = {object(1, "bolt", 5, 5), object(2, "nut", 6, 6, false, GripReason::TooWide),
                 object(3, "washer", 7, 7, false, GripReason::FingerCollision, true), object(4, std::nullopt, 8, 8),
                 object(5, "spring", 9, 9), object(6, "bolt", 3, 3),
                 object(7, "bolt", 4, 1, true, GripReason::None, true)};
  Recipe r{{"bolt", "tray"}, {"nut", "bin"}, {"washer", "bin"}};
  Sorting s = sort_objects(det, r, {{{"bolt", cv::Point2d(3.3, 3.2)}, "gave_up", "its pick failed every attempt"}});
  ASSERT_EQ(s.candidates.size(), 2u);
  EXPECT_EQ(s.candidates[0].index, 0u);
  EXPECT_FALSE(s.candidates[0].disturbs);
  EXPECT_EQ(s.candidates[1].index, 6u);
  EXPECT_TRUE(s.candidates[1].disturbs);  // feasible, but split from a neighbour
  ASSERT_EQ(s.skips.size(), 4u);
  EXPECT_EQ(s.skips[0].reason, "infeasible_grip");
  EXPECT_EQ(s.skips[0].detail, "too_wide");
  EXPECT_EQ(s.skips[1].reason, "touching");
  EXPECT_EQ(s.skips[2].reason, "unknown_class");
  EXPECT_EQ(s.skips[3].reason, "gave_up");  // within 1 cm of the object given up
  EXPECT_EQ(s.left.at("spring"), 1);
  // A clear maps everything, the unknown ones too.
  Sorting all = sort_objects(det, {{"*", "bin"}, {"unknown", "bin"}}, {});
  EXPECT_EQ(all.candidates.size(), 5u);
  EXPECT_TRUE(all.left.empty());
}

TEST(SortChoice, SkipDetailsComeFromTheGripsReason) {
  rbx1::vision::Scan det;
  det.objects = {object(1, "bolt", 5, 5, false, GripReason::TooWide, true),  // touching, but too wide anyway
                 object(2, "bolt", 9, 9, false, GripReason::None)};          // infeasible without a named reason
  Sorting s = sort_objects(det, {{"bolt", "tray"}}, {});
  ASSERT_EQ(s.skips.size(), 2u);
  EXPECT_EQ(s.skips[0].reason, "infeasible_grip");
  EXPECT_EQ(s.skips[0].detail, "too_wide");
  EXPECT_EQ(s.skips[1].reason, "infeasible_grip");
  EXPECT_EQ(s.skips[1].detail, "no feasible grip");
  EXPECT_TRUE(s.candidates.empty());
}

TEST(SortChoice, SameObjectIsTheNearestOfItsClassWithinACentimetre) {
  rbx1::vision::Scan det;
  det.objects = {object(1, "bolt", 5.0, 5.0), object(2, "bolt", 5.6, 5.0), object(3, "nut", 5.1, 5.0),
                 object(4, std::nullopt, 5.05, 5.0)};
  const auto* o = find_same(det, "bolt", cv::Point2d(5.4, 5.0));
  ASSERT_TRUE(o);
  EXPECT_EQ(o->index, 2);  // 0.2 cm away, not the first bolt 0.4 cm away, nor the nut nearer still
  EXPECT_EQ(find_same(det, "unknown", cv::Point2d(5.0, 5.0))->index, 4);
  EXPECT_FALSE(find_same(det, "bolt", cv::Point2d(7.0, 5.0)));  // 1.4 cm from the nearest bolt
  EXPECT_TRUE(same_object(det.objects[0], "bolt", cv::Point2d(5.0, 6.0)));  // exactly 1 cm
  EXPECT_FALSE(find_same(det, "bolt", std::nullopt));  // where it lay is unknown (uncalibrated)
  det.objects[1].centroid_cm.reset();
  EXPECT_EQ(find_same(det, "bolt", cv::Point2d(5.4, 5.0))->index, 1);  // an uncalibrated detection matches nothing
}

TEST(SortChoice, RankPrefersUndisturbingThenShortestTravel) {
  std::vector<Candidate> c{{0, "a", "tray", true, 100}, {1, "b", "tray", false, 900}, {2, "c", "tray", false, 300}};
  rank(c);
  EXPECT_EQ(c[0].index, 2u);
  EXPECT_EQ(c[1].index, 1u);
  EXPECT_EQ(c[2].index, 0u);
}

TEST(JobsRequest, FieldsOfSortClearRecipeSaveAndHistory) {
  Request r;
  Error e;
  ASSERT_TRUE(parse_request(R"({"cmd":"sort","recipe":"bins","max_picks":5})", r, e)) << e.message;
  EXPECT_EQ(r.command, Command::Sort);
  EXPECT_EQ(r.recipe, "bins");
  EXPECT_EQ(r.max_picks, 5);
  EXPECT_EQ(request_json(r), json::parse(R"({"cmd":"sort","recipe":"bins","max_picks":5})"));
  ASSERT_TRUE(parse_request(R"({"cmd":"sort","recipe":{"bolt":"tray","*":"bin"}})", r, e)) << e.message;
  EXPECT_EQ(r.recipe["*"], "bin");
  ASSERT_TRUE(parse_request(R"({"cmd":"clear","place":"bin"})", r, e));
  EXPECT_EQ(r.place, "bin");
  ASSERT_TRUE(parse_request(R"({"cmd":"recipe_save","name":"bins","recipe":{"bolt":"tray"}})", r, e));
  ASSERT_TRUE(parse_request(R"({"cmd":"history","limit":10,"job":3,"since":"2026-12-02","format":"csv"})", r, e));
  EXPECT_EQ(r.limit, 10);
  EXPECT_EQ(r.job, 3);
  ASSERT_TRUE(parse_request(R"({"cmd":"pause"})", r, e));
  EXPECT_EQ(r.command, Command::Pause);
  ASSERT_TRUE(parse_request(R"({"cmd":"recipes"})", r, e));
  EXPECT_EQ(r.command, Command::Recipes);
  // A sort and a clear run until the table is done: the console answers them when their started event comes.
  EXPECT_STREQ(command_spec(Command::Sort).started_event, "sort_started");
  EXPECT_STREQ(command_spec(Command::Clear).started_event, "sort_started");
  EXPECT_EQ(command_spec(Command::Pick).started_event, nullptr);

  EXPECT_FALSE(parse_request(R"({"cmd":"sort"})", r, e));
  EXPECT_EQ(e.code, "missing_field");
  EXPECT_FALSE(parse_request(R"({"cmd":"sort","recipe":{}})", r, e));
  EXPECT_EQ(e.code, "bad_field");
  EXPECT_FALSE(parse_request(R"({"cmd":"sort","recipe":"x","max_picks":0})", r, e));
  EXPECT_EQ(e.code, "bad_field");
  EXPECT_FALSE(parse_request(R"({"cmd":"clear","place":"bin","recipe":"x"})", r, e));
  EXPECT_EQ(e.code, "bad_field");
  EXPECT_FALSE(parse_request(R"({"cmd":"recipe_save","name":"x","recipe":"bins"})", r, e));
  EXPECT_EQ(e.code, "bad_field");  // a saved recipe is an object, not another's name
  EXPECT_FALSE(parse_request(R"({"cmd":"history","format":"xml"})", r, e));
  EXPECT_EQ(e.code, "bad_field");
  EXPECT_FALSE(parse_request(R"({"cmd":"pause","now":true})", r, e));
  EXPECT_EQ(e.code, "bad_field");
  EXPECT_FALSE(parse_request(R"({"cmd":"recipes","name":"bins"})", r, e));
  EXPECT_EQ(e.code, "bad_field");
}

// The second look (pick_plan.hpp): the camera moved straight over a point of the table, same height and yaw.
TEST(SecondLook, TheLookPoseMovesTheToolByTheShiftAtTheScanHeight) {
  const rbx1::arm::ArmConfig cfg;
  const rbx1::arm::ToolPose scan = rbx1::arm::tool_pose(cfg.links, cfg.scan);
  for (const auto& [dx, dy] : {std::pair{0.0, 0.0}, {60.0, -40.0}, {-70.0, 55.0}}) {
    rbx1::arm::Joints look{};
    std::string error;
    ASSERT_TRUE(look_pose(cfg, {dx, dy}, look, error)) << error;
    const rbx1::arm::ToolPose at = rbx1::arm::tool_pose(cfg.links, look);
    EXPECT_NEAR(at.x_mm, scan.x_mm + dx, 0.01);
    EXPECT_NEAR(at.y_mm, scan.y_mm + dy, 0.01);
    EXPECT_NEAR(at.z_mm, scan.z_mm, 0.01);
    EXPECT_NEAR(at.tilt_deg, scan.tilt_deg, 0.01);  // still straight down
  }
  rbx1::arm::Joints far{};
  std::string error;
  EXPECT_FALSE(look_pose(cfg, {2000.0, 0.0}, far, error));
  EXPECT_FALSE(error.empty());
}

TEST(SecondLook, ATablePointByTheMountOrNoneUncalibrated) {
  const rbx1::arm::ArmConfig cfg;  // the camera mount's planar map: base = origin + R(-90) F 10 cm
  const auto p = table_point(cfg, {0, 0}, cv::Point2d(2.0, 1.0));
  ASSERT_TRUE(p);
  const rbx1::arm::TablePoint t = rbx1::arm::vision_to_base(cfg, {2.0, 1.0}, 0);
  EXPECT_DOUBLE_EQ(p->x(), t.x_mm);
  EXPECT_DOUBLE_EQ(p->y(), t.y_mm);
  EXPECT_FALSE(table_point(cfg, {0, 0}, std::nullopt));
}
