// config.hpp - reads one TOML file section by section, range-checking every value; each error names its key.
// Every host part reads and checks its own section (Klipper-style); the daemon only strings them together.
#pragma once
#include <cstdint>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <toml++/toml.h>

namespace rbx1::config {

// Collected validation errors, each "key: problem", so one run reports them all.
class Errors {
 public:
  void add(const std::string& key, const std::string& problem) { messages_.push_back(key + ": " + problem); }
  bool ok() const { return messages_.empty(); }
  const std::vector<std::string>& messages() const { return messages_; }
  std::string joined() const;

 private:
  std::vector<std::string> messages_;
};

// One table of the file (or an absent one: then every value takes its default).
class Section {
 public:
  Section(const toml::table* table, std::string path, Errors& errors);

  double number(std::string_view key, double fallback, double min, double max);
  int64_t integer(std::string_view key, int64_t fallback, int64_t min, int64_t max);
  bool boolean(std::string_view key, bool fallback);
  std::string string(std::string_view key, const std::string& fallback);
  // A fixed-length array of numbers, each within [min, max].
  std::vector<double> numbers(std::string_view key, const std::vector<double>& fallback, double min, double max);
  Section section(std::string_view key);
  bool has(std::string_view key) const;
  // The table's key names in file order (empty when the table is absent), for tables of user-named entries.
  std::vector<std::string> keys() const;
  // Adds an error for each key in the table that no call above read (a typo must not pass silently).
  void reject_unknown();
  const std::string& path() const { return path_; }
  Errors& errors() { return errors_; }

 private:
  std::string key_path(std::string_view key) const;
  const toml::node* get(std::string_view key);

  const toml::table* table_;
  std::string path_;
  Errors& errors_;
  std::set<std::string, std::less<>> read_;
};

// Parses a TOML file; on failure adds "FILE:LINE:COL: message" to errors and returns an empty table.
toml::table load_file(const std::string& file, Errors& errors);
// Parses TOML text (tests, --check-config on stdin).
toml::table parse_text(std::string_view text, Errors& errors);

}  // namespace rbx1::config
