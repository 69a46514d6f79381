// library.cpp - reading, checking and atomically writing the taught-object library.
#include "library.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

#include <fcntl.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

namespace rbx1::vision {

using nlohmann::json;

bool load_library(const std::string& path, Library& out, std::string& error, bool allow_missing) {
  out.entries.clear();
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    if (allow_missing && errno == ENOENT) return true;
    error = path + ": cannot be read (" + std::strerror(errno) + ")";
    return false;
  }
  std::stringstream buf;
  buf << in.rdbuf();
  json doc = json::parse(buf.str(), nullptr, false);
  if (doc.is_discarded() || !doc.is_object()) {
    error = path + ": not a library (invalid JSON)";
    return false;
  }
  auto fail = [&](const std::string& why) {
    error = path + ": " + why;
    out.entries.clear();
    return false;
  };
  if (doc.value("format", "") != "rbx1-vision-library") return fail("not a library (format is not rbx1-vision-library)");
  if (!doc.contains("version") || doc["version"] != 1) return fail("unsupported library version");
  if (!doc.contains("bins") || doc["bins"] != kProfileBins) return fail("bins must be " + std::to_string(kProfileBins));
  if (!doc.contains("objects") || !doc["objects"].is_array()) return fail("objects must be an array");
  for (size_t i = 0; i < doc["objects"].size(); ++i) {
    const json& o = doc["objects"][i];
    std::string where = "objects[" + std::to_string(i) + "]";
    if (!o.is_object()) return fail(where + " must be an object");
    LibraryEntry e;
    if (!o.contains("name") || !o["name"].is_string() || o["name"].get<std::string>().empty())
      return fail(where + ".name must be a non-empty string");
    e.name = o["name"];
    if (o.contains("mirror_ok") && !o["mirror_ok"].is_boolean()) return fail(where + ".mirror_ok must be true or false");
    e.mirror_ok = o.value("mirror_ok", false);
    if (!o.contains("profile") || !o["profile"].is_array() || o["profile"].size() != size_t(kProfileBins))
      return fail(where + ".profile must hold " + std::to_string(kProfileBins) + " numbers");
    for (const json& v : o["profile"]) {
      if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < 0)
        return fail(where + ".profile must hold non-negative numbers");
      e.profile.push_back(v.get<double>());
    }
    if (!o.contains("area_px") || !o["area_px"].is_number() || !(o["area_px"].get<double>() > 0))
      return fail(where + ".area_px must be a positive number");
    e.area_px = o["area_px"];
    if (o.contains("area_cm2") && !o["area_cm2"].is_null()) {
      if (!o["area_cm2"].is_number() || !(o["area_cm2"].get<double>() > 0)) return fail(where + ".area_cm2 must be positive");
      e.area_cm2 = o["area_cm2"].get<double>();
    }
    e.elongation = o.value("elongation", 1.0);
    // "area" names the entry's area kind: "half_level" (taught since the half-level area), absent or "layer".
    const json kind = o.value("area", json("layer"));
    if (kind != "layer" && kind != "half_level") return fail(where + ".area must be \"half_level\" or \"layer\"");
    e.area_kind = kind == "half_level" ? AreaKind::HalfLevel : AreaKind::Layer;
    if (o.contains("threshold") && !o["threshold"].is_null()) {
      if (!o["threshold"].is_number() || !(o["threshold"].get<double>() > 0 && o["threshold"].get<double>() <= 1))
        return fail(where + ".threshold must be a number in (0, 1]");
      e.threshold = o["threshold"].get<double>();
    }
    out.entries.push_back(std::move(e));
  }
  return true;
}

bool save_library(const std::string& path, const Library& lib, std::string& error) {
  json doc = {{"format", "rbx1-vision-library"}, {"version", 1}, {"bins", kProfileBins}, {"objects", json::array()}};
  for (const LibraryEntry& e : lib.entries) {
    json o = {{"name", e.name}, {"mirror_ok", e.mirror_ok}, {"area_px", e.area_px}, {"elongation", e.elongation}};
    o["area_cm2"] = e.area_cm2 ? json(*e.area_cm2) : json(nullptr);
    if (e.area_kind == AreaKind::HalfLevel) o["area"] = "half_level";
    if (e.threshold) o["threshold"] = std::round(*e.threshold * 1e4) / 1e4;
    json p = json::array();
    for (double v : e.profile) p.push_back(std::round(v * 1e5) / 1e5);
    o["profile"] = p;
    doc["objects"].push_back(o);
  }
  std::string text = doc.dump(1) + "\n";
  std::string tmp = path + ".tmp." + std::to_string(getpid());
  int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) {
    error = path + ": cannot write (" + std::strerror(errno) + ")";
    return false;
  }
  size_t done = 0;
  while (done < text.size()) {
    ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n <= 0) {
      error = path + ": write failed (" + std::strerror(errno) + ")";
      ::close(fd);
      ::unlink(tmp.c_str());
      return false;
    }
    done += size_t(n);
  }
  bool ok = ::fsync(fd) == 0;
  ok = ::close(fd) == 0 && ok;
  if (!ok || std::rename(tmp.c_str(), path.c_str()) != 0) {
    error = path + ": cannot replace (" + std::strerror(errno) + ")";
    ::unlink(tmp.c_str());
    return false;
  }
  return true;
}

void upsert(Library& lib, LibraryEntry entry) {
  for (LibraryEntry& e : lib.entries) {
    if (e.name == entry.name) {
      e = std::move(entry);
      return;
    }
  }
  lib.entries.push_back(std::move(entry));
}

}  // namespace rbx1::vision
