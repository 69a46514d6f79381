// jobs_request.hpp - the cell jobs' request checks beyond their fields' types (command_table.cpp calls them).
#pragma once
#include <nlohmann/json.hpp>

#include "request.hpp"

namespace rbx1::daemon {

// sort: "recipe" is a saved recipe's name or an object of class -> place names.
bool check_sort_request(const nlohmann::json& request, Request& out, Error& error);
// recipe_save: "recipe" is an object of class -> place names (a name would save nothing).
bool check_recipe_save_request(const nlohmann::json& request, Request& out, Error& error);

}  // namespace rbx1::daemon
