// jobs_test.cpp - the cell jobs' parts without an arm: recipes (checks naming the offender, "*" and "unknown",
// the recipes file), the choice of the next object (skip reasons, ranking), the requests' fields.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "command_table.hpp"
#include "recipes.hpp"
#include "request.hpp"
#include "sort_choice.hpp"

namespace fs = std::filesystem;
using namespace rbx1::daemon;
using nlohmann::json;

namespace {

const std::set<std::string> kPlaces{"tray", "bin", "reject"};
const std::set<std::string> kClasses{"bolt", "nut", "washer"};

json object(int index, json label, double x, double y, bool feasible = true, json reason = nullptr,
            bool touching = false) {
  return {{"index", index}, {"label", label}, {"match_score", label.is_null() ? json(nullptr) : json(0.9)},
          {"centroid_cm", {x, y}}, {"touching", touching},
          {"grip", {{"opening_cm", 1.0}, {"angle_deg", 10.0}, {"feasible", feasible}, {"reason", reason}}}};
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
  EXPECT_EQ(place_for(r, nullptr), std::nullopt);  // "*" is every identified class, not the unknown ones
  r["unknown"] = "reject";
  EXPECT_EQ(place_for(r, nullptr), "reject");
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
  json det{{"objects",
            {object(1, "bolt", 5, 5), object(2, "nut", 6, 6, false, "too_wide"),
             object(3, "washer", 7, 7, false, "finger_collision", true), object(4, nullptr, 8, 8),
             object(5, "spring", 9, 9), object(6, "bolt", 3, 3), object(7, "bolt", 4, 1, true, nullptr, true)}}};
  Recipe r{{"bolt", "tray"}, {"nut", "bin"}, {"washer", "bin"}};
  Sorting s = sort_objects(det, r, {{"bolt", json::array({3.3, 3.2})}});
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
