// jobs_request.cpp - the cell jobs' request checks beyond their fields' types: a sort's recipe is a saved recipe's
// name or a map of class to place names; a saved recipe is a map (recipes.hpp checks places and classes when run).
#include "jobs_request.hpp"

#include "command_table.hpp"

namespace rbx1::daemon {

namespace {

bool bad(Error& error, const std::string& message) {
  error = {ErrorCode::BadField, message};
  return false;
}

bool recipe_map(const nlohmann::json& r) {
  if (!r.is_object() || r.empty()) return false;
  for (const auto& [cls, place] : r.items())
    if (!valid_name(nlohmann::json(cls)) || !valid_name(place)) return false;
  return true;
}

constexpr const char* kMapForm = "an object of class to place, e.g. {\"bolt\": \"tray\", \"*\": \"bin\"} (names of 1-64 printable characters)";

}  // namespace

bool check_sort_request(const nlohmann::json&, Request& out, Error& error) {
  if (valid_name(out.recipe) || recipe_map(out.recipe)) return true;
  return bad(error, std::string("\"recipe\" must be a saved recipe's name or ") + kMapForm);
}

bool check_recipe_save_request(const nlohmann::json&, Request& out, Error& error) {
  if (recipe_map(out.recipe)) return true;
  return bad(error, std::string("\"recipe\" must be ") + kMapForm);
}

}  // namespace rbx1::daemon
