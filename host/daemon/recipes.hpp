// recipes.hpp - sort recipes: which place each class goes to ({"bolt": "tray", "*": "reject", "unknown": "bin"}),
// kept by name in STATE_DIR/recipes.json (written atomically), checked against the places and the library.
#pragma once
#include <map>
#include <optional>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

namespace rbx1::daemon {

inline constexpr const char* kRecipesFile = "recipes.json";  // {"NAME": {"CLASS": "PLACE", ...}, ...}
inline constexpr const char* kAnyClass = "*";                // every identified class the recipe does not name
inline constexpr const char* kUnknownClass = "unknown";      // objects no library entry matches

using Recipe = std::map<std::string, std::string>;  // class -> place

// A JSON object of class -> place strings, not empty. false + error naming what is wrong.
bool recipe_from_json(const nlohmann::json& j, Recipe& out, std::string& error);
nlohmann::json recipe_json(const Recipe& r);
// Every place is one of places, every class one of classes (or "*", "unknown"); else error naming the first
// offender and what is known.
bool check_recipe(const Recipe& r, const std::set<std::string>& places, const std::set<std::string>& classes,
                  std::string& error);
// Where an object with this label goes (no label: unknown): its own key, else "*" for an identified class.
// Nothing: the recipe leaves it on the table.
std::optional<std::string> place_for(const Recipe& r, const std::optional<std::string>& label);

// The saved recipes (dir/recipes.json). Reads fresh on each call: the file is small and the console may edit it.
class RecipeBook {
 public:
  explicit RecipeBook(std::string dir) : dir_(std::move(dir)) {}
  std::string path() const { return dir_ + "/" + kRecipesFile; }
  // All saved recipes ({} when the file is missing); false + "PATH: reason" when it is corrupt.
  bool load(std::map<std::string, Recipe>& out, std::string& error) const;
  bool find(const std::string& name, Recipe& out, std::string& error) const;  // error "no recipe NAME (saved: ...)"
  bool save(const std::string& name, const Recipe& r, std::string& error) const;  // adds or replaces, atomically

 private:
  std::string dir_;
};

}  // namespace rbx1::daemon
