// recipes.cpp - recipes from and to JSON, their check against places and library, the recipes file.
#include "recipes.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>

#include "atomic_file.hpp"

namespace rbx1::daemon {

namespace {
std::string joined(const std::set<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s.empty() ? "none" : s;
}

bool printable_name(const std::string& s) {
  if (s.empty() || s.size() > 64) return false;
  for (unsigned char c : s)
    if (c < 0x20 || c == 0x7f) return false;
  return true;
}
}  // namespace

bool recipe_from_json(const nlohmann::json& j, Recipe& out, std::string& error) {
  if (!j.is_object() || j.empty()) {
    error = "a recipe is a JSON object of class to place, e.g. {\"bolt\": \"tray\", \"*\": \"bin\"}";
    return false;
  }
  out.clear();
  for (const auto& [cls, place] : j.items()) {
    if (!printable_name(cls) || !place.is_string() || !printable_name(place.get<std::string>())) {
      error = "recipe entry \"" + cls.substr(0, 40) + "\": class and place must be names (1-64 printable characters)";
      return false;
    }
    out[cls] = place.get<std::string>();
  }
  return true;
}

nlohmann::json recipe_json(const Recipe& r) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [cls, place] : r) j[cls] = place;
  return j;
}

bool check_recipe(const Recipe& r, const std::set<std::string>& places, const std::set<std::string>& classes,
                  std::string& error) {
  for (const auto& [cls, place] : r) {
    if (cls != kAnyClass && cls != kUnknownClass && !classes.count(cls)) {
      error = "recipe: the library knows no class \"" + cls + "\" (known: " + joined(classes) + ", and \"*\", \"unknown\")";
      return false;
    }
    if (!places.count(place)) {
      error = "recipe: " + cls + " -> no place \"" + place + "\" in [arm] places (known: " + joined(places) + ")";
      return false;
    }
  }
  return true;
}

std::optional<std::string> place_for(const Recipe& r, const std::optional<std::string>& label) {
  if (auto it = r.find(label.value_or(kUnknownClass)); it != r.end()) return it->second;
  if (label)
    if (auto it = r.find(kAnyClass); it != r.end()) return it->second;
  return std::nullopt;
}

bool RecipeBook::load(std::map<std::string, Recipe>& out, std::string& error) const {
  out.clear();
  std::error_code ec;
  if (!std::filesystem::exists(path(), ec)) return true;
  std::ifstream f(path());
  std::stringstream ss;
  ss << f.rdbuf();
  auto j = nlohmann::json::parse(ss.str(), nullptr, false);
  if (!f || j.is_discarded() || !j.is_object()) {
    error = path() + ": not a JSON object of recipes";
    return false;
  }
  for (const auto& [name, body] : j.items()) {
    std::string why;
    if (!recipe_from_json(body, out[name], why)) {
      error = path() + ": recipe \"" + name + "\": " + why;
      return false;
    }
  }
  return true;
}

bool RecipeBook::find(const std::string& name, Recipe& out, std::string& error) const {
  std::map<std::string, Recipe> all;
  if (!load(all, error)) return false;
  auto it = all.find(name);
  if (it == all.end()) {
    std::set<std::string> names;
    for (const auto& [n, r] : all) names.insert(n);
    error = "no recipe \"" + name + "\" in " + path() + " (saved: " + joined(names) + ")";
    return false;
  }
  out = it->second;
  return true;
}

bool RecipeBook::save(const std::string& name, const Recipe& r, std::string& error) const {
  if (!printable_name(name)) {
    error = "a recipe's name must be 1-64 printable characters";
    return false;
  }
  std::map<std::string, Recipe> all;
  if (!load(all, error)) return false;  // a corrupt file is never overwritten
  all[name] = r;
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [n, rec] : all) j[n] = recipe_json(rec);
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  return write_file_atomic(path(), j.dump(2) + "\n", error);
}

}  // namespace rbx1::daemon
