// detector.hpp - the whole method on one frame: isolation, geometry, pose, identification, grip (pixels only).
#pragma once
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "grip.hpp"
#include "identify.hpp"
#include "isolate.hpp"
#include "library.hpp"
#include "pose.hpp"
#include "shadow.hpp"
#include "types.hpp"

namespace rbx1::vision {

struct DetectorOptions {
  Polarity objects = Polarity::Auto;
  IsolationOptions isolation;
  PoseOptions pose;
  GripOptions grip;
  MatchOptions match;
  bool compensate_light = true;  // with a known background: fit gain and offset to the scene's light first
  bool shadows = true;           // with a known colour background and colour frame: shade is table (shadow.hpp)
  ShadowOptions shadow;
  GreyShadeOptions grey_shade;   // with a known grey background: shade found by its soft edges and caster
  double px_per_cm = 0;  // when > 0, identification compares sizes in cm^2 (entries taught with a scale)
};

struct Detection {
  cv::Size size;
  int sign = -1;                       // polarity used: -1 dark objects, +1 light, 0 both
  LightFit light;                      // the light change fitted against the known background
  int shadow_px = 0;                   // pixels taken as the table in shade
  Isolation isolation;                 // label image (neighbours for finger clearance)
  std::vector<DetectedObject> objects;
  std::vector<std::vector<double>> profiles;  // identity profile per object
  std::vector<std::string> warnings;   // why the objects found may be wrong or missing (the method could not decide)
};

// The frame and the known background in colour (CV_8UC3 BGR, the grey images' size), for the shadow test.
struct ColourImages {
  cv::Mat frame, background;
};

// gray: 8-bit frame; background_gray: empty for automatic modelling. lib may be null (no identification).
// colour (optional, with a background): shade on a coloured table is table (DetectorOptions::shadows).
// false + error for a background of another size or an all-foreground frame.
bool detect(const cv::Mat& gray, const cv::Mat& background_gray, const DetectorOptions& opt, const Library* lib,
            Detection& out, std::string& error, const ColourImages* colour = nullptr);

}  // namespace rbx1::vision
