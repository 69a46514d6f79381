// detector.cpp - runs the paper's steps I-V per object layer (each on its own ROI).
#include "detector.hpp"

#include "background.hpp"
#include "geometry.hpp"

namespace rbx1::vision {

bool detect(const cv::Mat& gray, const cv::Mat& background_gray, const DetectorOptions& opt, const Library* lib,
            Detection& out, std::string& error, const ColourImages* colour) {
  out = Detection{};
  out.size = gray.size();
  Contrast con;
  bool have_con = false;
  // The isolation's dark polarity, labelled in the grey shade's own pass when the shade leaves the background
  // as it is (no shade: the usual case).
  cv::Mat dark_labels;
  std::vector<Component> dark_comps;
  Labelling dark{0, 0, 1, &dark_labels, &dark_comps, false, -1};  // above_high stays -1 unless labelled
  bool use_dark = false;
  if (!background_gray.empty()) {
    cv::Mat bg = background_gray;
    if (opt.compensate_light && bg.size() == gray.size()) out.light = compensate_light(gray, background_gray, &bg);
    if (opt.shadows && colour && bg.size() == gray.size() && coloured_background(colour->background, opt.shadow)) {
      // The table in shade is table: there the background takes the frame's own grey (no contrast).
      cv::Mat shade;
      out.shadow_px = shadow_mask(colour->frame, colour->background, out.light, opt.shadow, shade);
      if (out.shadow_px > 0) {
        bg = bg.clone();
        gray.copyTo(bg, shade);
      }
    } else if (opt.shadows && bg.size() == gray.size()) {
      // A grey table: the shade found by its soft edges and its caster; the background in that shade.
      cv::Mat shade, shaded;
      const bool dark_objects = opt.objects != Polarity::Light;
      if (dark_objects) {  // the levels come from the contrast against this background (same size: no error)
        have_con = contrast_from_background(gray, bg, opt.objects, opt.isolation.min_contrast, con, error);
        isolation_levels(con, opt.isolation, dark.low, dark.high);
        dark_labels = label_frame(gray.size());
      }
      out.shadow_px = grey_shade_mask(gray, bg, opt.grey_shade, shade, shaded, dark_objects ? &dark : nullptr);
      if (out.shadow_px > 0) {
        bg = shaded;
        have_con = false;
      } else {
        use_dark = have_con && dark.above_high >= 0;
      }
    }
    if (!have_con && !contrast_from_background(gray, bg, opt.objects, opt.isolation.min_contrast, con, error))
      return false;
  } else {
    contrast_auto(gray, opt.objects, opt.isolation.min_contrast, con);
    if (!con.note.empty()) out.warnings.push_back(con.note);
  }
  out.sign = con.sign;
  if (!isolate(con, opt.isolation, out.isolation, error, use_dark ? &dark : nullptr)) return false;
  for (Layer& layer : out.isolation.layers) {
    DetectedObject o;
    if (!measure_geometry(layer, o.geometry)) continue;
    o.pose = estimate_pose(o.geometry, opt.pose);
    o.touching = layer.touching;
    RayHits hits = cast_rays(o.geometry, opt.grip.lines);
    GripOptions go = opt.grip;
    if (o.touching && (go.finger_width_px <= 0 || go.finger_depth_px <= 0)) {
      // A touching neighbour is always checked: with no finger size given, a thin finger still may not
      // land on it (which is what closing at the junction would do).
      go.finger_width_px = 3, go.finger_depth_px = 3;
    }
    o.grip = choose_grip(o.geometry, hits, layer.label, out.isolation.labels, out.isolation.obstacle, go, o.chord_phi,
                         o.chord_d);
    std::vector<double> profile = identity_profile(o.geometry, o.pose, hits, opt.grip.lines);
    if (lib && !lib->entries.empty()) {
      const SeenArea area = SeenArea::of(o.geometry, opt.px_per_cm);
      o.identity = identity_of(*lib, identify(*lib, profile, area, o.pose.elongation, opt.match), opt.match);
    }
    o.layer = std::move(layer);
    o.index = int(out.objects.size()) + 1;
    out.objects.push_back(std::move(o));
    out.profiles.push_back(std::move(profile));
  }
  return true;
}

}  // namespace rbx1::vision
