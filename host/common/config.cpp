// config.cpp - typed, range-checked reads from TOML tables with errors that name the key.
#include "config.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

namespace rbx1::config {

std::string Errors::joined() const {
  std::string out;
  for (const auto& m : messages_) out += (out.empty() ? "" : "\n") + m;
  return out;
}

Section::Section(const toml::table* table, std::string path, Errors& errors)
    : table_(table), path_(std::move(path)), errors_(errors) {}

std::string Section::key_path(std::string_view key) const {
  return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
}

const toml::node* Section::get(std::string_view key) {
  read_.emplace(key);
  return table_ ? table_->get(key) : nullptr;
}

bool Section::has(std::string_view key) const { return table_ && table_->contains(key); }

std::vector<std::string> Section::keys() const {
  std::vector<std::string> out;
  if (table_) {
    for (const auto& [k, v] : *table_) out.emplace_back(k.str());
  }
  return out;
}

static std::string range_text(double min, double max) {
  std::ostringstream s;
  s << "must be within [" << min << ", " << max << "]";
  return s.str();
}

double Section::number(std::string_view key, double fallback, double min, double max) {
  const toml::node* n = get(key);
  if (!n) return fallback;
  std::optional<double> v = n->is_integer() ? std::optional<double>(double(*n->value<int64_t>())) : n->value<double>();
  if (!v || !std::isfinite(*v)) {
    errors_.add(key_path(key), "must be a number");
    return fallback;
  }
  if (*v < min || *v > max) {
    errors_.add(key_path(key), range_text(min, max) + ", got " + std::to_string(*v));
    return fallback;
  }
  return *v;
}

int64_t Section::integer(std::string_view key, int64_t fallback, int64_t min, int64_t max) {
  const toml::node* n = get(key);
  if (!n) return fallback;
  if (!n->is_integer()) {
    errors_.add(key_path(key), "must be an integer");
    return fallback;
  }
  int64_t v = *n->value<int64_t>();
  if (v < min || v > max) {
    errors_.add(key_path(key), range_text(double(min), double(max)) + ", got " + std::to_string(v));
    return fallback;
  }
  return v;
}

bool Section::boolean(std::string_view key, bool fallback) {
  const toml::node* n = get(key);
  if (!n) return fallback;
  if (!n->is_boolean()) {
    errors_.add(key_path(key), "must be true or false");
    return fallback;
  }
  return *n->value<bool>();
}

std::string Section::string(std::string_view key, const std::string& fallback) {
  const toml::node* n = get(key);
  if (!n) return fallback;
  if (!n->is_string()) {
    errors_.add(key_path(key), "must be a string");
    return fallback;
  }
  return *n->value<std::string>();
}

std::vector<double> Section::numbers(std::string_view key, const std::vector<double>& fallback, double min, double max) {
  const toml::node* n = get(key);
  if (!n) return fallback;
  const toml::array* a = n->as_array();
  if (!a || a->size() != fallback.size()) {
    errors_.add(key_path(key), "must be an array of " + std::to_string(fallback.size()) + " numbers");
    return fallback;
  }
  std::vector<double> out;
  for (size_t i = 0; i < a->size(); ++i) {
    const toml::node& e = *a->get(i);
    std::optional<double> v = e.is_integer() ? std::optional<double>(double(*e.value<int64_t>())) : e.value<double>();
    std::string where = key_path(key) + "[" + std::to_string(i) + "]";
    if (!v || !std::isfinite(*v)) {
      errors_.add(where, "must be a number");
      return fallback;
    }
    if (*v < min || *v > max) {
      errors_.add(where, range_text(min, max) + ", got " + std::to_string(*v));
      return fallback;
    }
    out.push_back(*v);
  }
  return out;
}

Section Section::section(std::string_view key) {
  const toml::node* n = get(key);
  if (n && !n->is_table()) {
    errors_.add(key_path(key), "must be a table");
    n = nullptr;
  }
  return Section(n ? n->as_table() : nullptr, key_path(key), errors_);
}

void Section::reject_unknown() {
  if (!table_) return;
  for (const auto& [k, v] : *table_) {
    if (!read_.count(k.str())) errors_.add(key_path(k.str()), "unknown key");
  }
}

static toml::table parse(std::string_view text, const std::string& source, Errors& errors) {
  try {
    return toml::parse(text, source);
  } catch (const toml::parse_error& e) {
    std::ostringstream s;
    s << source << ":" << e.source().begin.line << ":" << e.source().begin.column;
    errors.add(s.str(), std::string(e.description()));
    return {};
  }
}

toml::table load_file(const std::string& file, Errors& errors) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    errors.add(file, "cannot be read");
    return {};
  }
  std::stringstream buf;
  buf << in.rdbuf();
  return parse(buf.str(), file, errors);
}

toml::table parse_text(std::string_view text, Errors& errors) { return parse(text, "config", errors); }

}  // namespace rbx1::config
