// library.hpp - the library of taught objects (rbx1 teach): JSON file, validated on load, written atomically.
#pragma once
#include <optional>
#include <string>
#include <vector>

namespace rbx1::vision {

inline constexpr int kProfileBins = 180;  // identity profile: outermost r every 2 degrees from the axis

// Which area an entry's size and profile scale are measured by (Geometry): the half level's (entries taught now),
// or the soft layer's sum (libraries taught before; it counts faint shadow, so it varied with the part's grey).
enum class AreaKind { Layer, HalfLevel };

struct LibraryEntry {
  std::string name;
  bool mirror_ok = false;            // a mirror image of the object is the same object (flipped part)
  std::vector<double> profile;       // kProfileBins values of r_out / sqrt(area), from the reference orientation
  double area_px = 0;
  std::optional<double> area_cm2;    // when taught with a calibration
  AreaKind area_kind = AreaKind::Layer;  // the area of area_px, area_cm2 and the profile's scale
  double elongation = 1;
  // Lowest score that is this object (learnt when teaching from its own views, identify.hpp learn_threshold);
  // none in libraries taught before issue 27: the global MatchOptions::threshold (0.5) applies.
  std::optional<double> threshold;
};

struct Library {
  std::vector<LibraryEntry> entries;
};

// A missing file is an empty library only when allow_missing. false + error "PATH: reason" otherwise.
bool load_library(const std::string& path, Library& out, std::string& error, bool allow_missing = false);
// Writes PATH.tmp then renames it over PATH, so readers never see a half-written library.
bool save_library(const std::string& path, const Library& lib, std::string& error);
// Adds or replaces (same name) an entry.
void upsert(Library& lib, LibraryEntry entry);

}  // namespace rbx1::vision
