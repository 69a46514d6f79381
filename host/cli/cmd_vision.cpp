// cmd_vision.cpp - rbx1 detect / teach / plot: the perception commands (shared/DESIGN.md fixes detect).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "commands.hpp"
#include "draw.hpp"
#include "identify.hpp"
#include "image_io.hpp"
#include "library.hpp"
#include "scan_json.hpp"
#include "vision.hpp"

namespace rbx1::cli {
namespace {

namespace v = rbx1::vision;

// Options shared by the three commands: how to find objects and how to scale them.
struct Common {
  std::string image;
  std::string objects = "auto";
  v::VisionOptions opt;
};

// A strictly positive finite number, with a short message (CLI11's PositiveNumber prints DBL_MIN in full).
const CLI::Validator kPositive(
    [](std::string& text) -> std::string {
      double v = 0;
      size_t used = 0;
      try {
        v = std::stod(text, &used);
      } catch (const std::exception&) {
        return "not a number: " + text;
      }
      if (used != text.size() || !std::isfinite(v)) return "not a number: " + text;
      if (v <= 0) return "must be greater than 0, got " + text;
      return {};
    },
    "POSITIVE");

void add_common(CLI::App* c, Common& s, bool image_required = true) {
  c->add_option("IMAGE", s.image, "image file of the scene")->required(image_required);
  c->add_option("--background", s.opt.background_path, "image of the empty scene (same size); default: modelled");
  c->add_option("--objects", s.objects, "objects darker or lighter than the background")
      ->check(CLI::IsMember({"auto", "dark", "light"}));
  auto* ppc = c->add_option("--px-per-cm", s.opt.px_per_cm, "image scale (pixels per cm)")->check(kPositive);
  auto* cal = c->add_option("--calibration", s.opt.calibration_path, "calibration file from rbx1 calibrate");
  ppc->excludes(cal);
  c->add_option("--gripper-max-cm", s.opt.gripper_max_cm, "widest gripper opening (cm)")->check(kPositive);
  c->add_option("--gripper-min-cm", s.opt.gripper_min_cm, "narrowest opening that holds an object (cm)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--gripper-min-px", s.opt.gripper_min_px, "the same when uncalibrated (px)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--finger-width-cm", s.opt.finger_width_cm, "finger width across the closing line (cm)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--finger-depth-cm", s.opt.finger_depth_cm, "finger depth outward from the contact (cm)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--finger-width-px", s.opt.finger_width_px, "finger width when uncalibrated (px; 0: no check)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--finger-depth-px", s.opt.finger_depth_px, "finger depth when uncalibrated (px)")
      ->check(CLI::NonNegativeNumber);
  c->add_option("--min-area-px", s.opt.min_area_px, "smaller regions are specks (default: 40 at 640x480, scaled with the frame)")->check(kPositive);
  c->add_option("--match-threshold", s.opt.match_threshold, "identification score below this: unknown")
      ->check(CLI::Range(0.0, 1.0));
}

int fail(const char* cmd, const std::string& message) {
  std::fprintf(stderr, "rbx1 %s: %s\n", cmd, message.c_str());
  return 2;
}

// Loads the image and runs the method. Returns 0 or the exit code after printing the error.
int run(const char* cmd, Common& s, std::unique_ptr<v::Vision>& vis, v::Detection& det, cv::Mat& processed) {
  v::parse_polarity(s.objects, s.opt.objects);
  std::string error;
  cv::Mat frame;
  if (!v::read_image(s.image, frame, error)) return fail(cmd, error);
  vis = v::Vision::create(s.opt, error);
  if (!vis) return fail(cmd, error);
  if (!vis->run(frame, det, processed, error)) return fail(cmd, s.image + ": " + error);
  return 0;
}

void add_detect(CLI::App& app, int& exit_code) {
  auto s = std::make_shared<Common>();
  auto annotate_path = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  CLI::App* c = app.add_subcommand("detect", "find objects, their pose and grips (paper Fig. 21 report or --json)");
  add_common(c, *s);
  c->add_option("--library", s->opt.library_path, "taught objects (rbx1 teach) for identification");
  c->add_option("--annotate", *annotate_path, "write the annotated image (paper Fig. 20) here");
  c->add_flag("--json", *json, "one JSON document on stdout (shared/DESIGN.md)");
  c->callback([s, annotate_path, json, &exit_code] {
    std::unique_ptr<v::Vision> vis;
    v::Detection det;
    cv::Mat processed;
    if ((exit_code = run("detect", *s, vis, det, processed)) != 0) return;
    if (!annotate_path->empty()) {
      bool ok = false;
      try {
        ok = cv::imwrite(*annotate_path, v::annotate(processed, det, vis->calibrated()));
      } catch (const cv::Exception&) {
        ok = false;
      }
      if (!ok) {
        exit_code = fail("detect", *annotate_path + ": cannot write the annotated image");
        return;
      }
    }
    if (*json) {
      for (const std::string& w : det.warnings) std::fprintf(stderr, "rbx1 detect: warning: %s\n", w.c_str());
      std::printf("%s\n", nlohmann::json(vis->scan(det)).dump().c_str());
    } else {
      std::fputs(vis->report(det).c_str(), stdout);
    }
  });
}

void add_teach(CLI::App& app, int& exit_code) {
  auto s = std::make_shared<Common>();
  auto name = std::make_shared<std::string>();
  auto library = std::make_shared<std::string>();
  auto mirror_ok = std::make_shared<bool>(false);
  auto from_camera = std::make_shared<int>(0);
  auto socket = std::make_shared<std::string>(default_socket());
  CLI::App* c = app.add_subcommand("teach", "add the single object in IMAGE to a library of known objects, or object "
                                            "INDEX of rbx1d's live scan to its library (--from-camera)");
  add_common(c, *s, false);
  c->add_option("--name", *name, "the object's name")->required();
  c->add_option("--library", *library, "library file (created if missing; written atomically)");
  c->add_flag("--mirror-ok", *mirror_ok, "a mirror image of this object is the same object");
  c->add_option("--from-camera", *from_camera, "teach object INDEX (as numbered by rbx1 scan) through rbx1d")
      ->check(CLI::PositiveNumber);
  c->add_option("--socket", *socket, "rbx1d control socket, with --from-camera (default $RBX1_SOCKET)");
  c->callback([s, name, library, mirror_ok, from_camera, socket, &exit_code] {
    if (name->empty()) {
      exit_code = fail("teach", "--name must not be empty");
      return;
    }
    if (*from_camera > 0) {
      if (!s->image.empty() || !library->empty()) {
        exit_code = fail("teach", "--from-camera teaches into rbx1d's state library: no IMAGE, no --library");
        return;
      }
      daemon::Request r;
      r.command = daemon::Command::Teach;
      r.index = *from_camera;
      r.name = *name;
      r.mirror_ok = *mirror_ok;
      exit_code = run_daemon_request(*socket, false, r);
      return;
    }
    if (s->image.empty() || library->empty()) {
      exit_code = fail("teach", "give IMAGE and --library FILE, or --from-camera INDEX");
      return;
    }
    std::string error;
    v::Library lib;
    if (!v::load_library(*library, lib, error, true)) {
      exit_code = fail("teach", error);
      return;
    }
    std::unique_ptr<v::Vision> vis;
    v::Detection det;
    cv::Mat processed;
    if ((exit_code = run("teach", *s, vis, det, processed)) != 0) return;
    if (det.objects.size() != 1) {
      exit_code = fail("teach", s->image + ": needs exactly one object, found " + std::to_string(det.objects.size()));
      return;
    }
    v::SelfViews views;
    v::LibraryEntry entry = vis->teach_entry(det, 0, *name, *mirror_ok, &views);
    // Taught anyway (nothing is picked wrongly: an ambiguous object is never taken), but never silently.
    const auto twins = v::lookalikes(lib, entry, vis->detector_options().match);
    v::upsert(lib, std::move(entry));
    if (!v::save_library(*library, lib, error)) {
      exit_code = fail("teach", error);
      return;
    }
    std::printf("taught \"%s\" (%zu objects in %s); its own views score %.3f-%.3f, accepted from %.3f\n",
                name->c_str(), lib.entries.size(), library->c_str(), views.worst, views.median, views.threshold);
    for (const auto& t : twins) std::fprintf(stderr, "rbx1 teach: warning: %s\n", v::lookalike_warning(*name, t).c_str());
  });
}

void add_plot(CLI::App& app, int& exit_code) {
  auto s = std::make_shared<Common>();
  auto index = std::make_shared<int>(1);
  auto dir = std::make_shared<std::string>();
  CLI::App* c = app.add_subcommand("plot", "PNG plots of one object's r-theta profile and D(theta)");
  add_common(c, *s);
  c->add_option("--object", *index, "object number (as in detect)")->check(kPositive);
  c->add_option("--out-dir", *dir, "folder for the PNG files (created if missing)")->required();
  c->callback([s, index, dir, &exit_code] {
    std::unique_ptr<v::Vision> vis;
    v::Detection det;
    cv::Mat processed;
    if ((exit_code = run("plot", *s, vis, det, processed)) != 0) return;
    if (*index > int(det.objects.size())) {
      exit_code = fail("plot", s->image + ": no object #" + std::to_string(*index) + " (found " +
                                   std::to_string(det.objects.size()) + ")");
      return;
    }
    std::error_code ec;
    std::filesystem::create_directories(*dir, ec);
    std::string error;
    if (ec || !v::write_plots(det.objects[size_t(*index - 1)], *dir, error)) {
      exit_code = fail("plot", ec ? *dir + ": " + ec.message() : error);
      return;
    }
    std::printf("wrote %s/object-%d-{profile,profile-ref,opening}.png\n", dir->c_str(), *index);
  });
}

}  // namespace

void add_vision_commands(CLI::App& app, int& exit_code) {
  add_detect(app, exit_code);
  add_teach(app, exit_code);
  add_plot(app, exit_code);
}

}  // namespace rbx1::cli
