// cmd_operator.cpp - rbx1 jog | pose save | place save | background | calibrate-workspace | markers: the operator's
// commands (all but markers are rbx1d requests, the same ones the web console sends).
#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "commands.hpp"
#include "markers.hpp"
#include "rbx1_messages.h"

namespace rbx1::cli {

namespace {

struct Options {
  std::string socket;
  bool json = false;
  int joint = 0;
  int32_t steps = 0;
  double deg = 0;
  std::vector<double> mm;
  std::string name;
  int frames = 0;
  std::string action;
  int marker = -1;
};

CLI::App* add(CLI::App& parent, const std::shared_ptr<Options>& o, const char* name, const char* help) {
  CLI::App* sub = parent.add_subcommand(name, help);
  sub->add_option("--socket", o->socket, "rbx1d control socket (default $RBX1_SOCKET or /run/rbx1/rbx1d.sock)");
  sub->add_flag("--json", o->json, "print the raw JSON event lines");
  return sub;
}

daemon::Request calib_request(const std::string& action, int marker = 0) {
  daemon::Request r;
  r.command = daemon::Command::CalibrateWorkspace;
  r.action = action;
  r.index = marker;
  return r;
}

void print_fit(const nlohmann::json& f) {
  std::printf("model: %s over %zu markers\n", f.value("model", "?").c_str(), f["markers"].size());
  std::printf("  marker  residual_mm  leave-one-out_mm\n");
  for (const auto& m : f["markers"])
    std::printf("  %6d  %11.3f  %16s\n", m["id"].get<int>(), m["residual_mm"].get<double>(),
                m["loo_mm"].is_number() ? std::to_string(m["loo_mm"].get<double>()).substr(0, 6).c_str() : "-");
  std::printf("RMS residual: %.3f mm (bound %.3f), worst leave-one-out: %s mm (bound %.3f)\n", f["rms_mm"].get<double>(),
              f["bounds"]["max_rms_mm"].get<double>(), f["max_loo_mm"].dump().c_str(),
              f["bounds"]["max_loo_mm"].get<double>());
  if (!f.value("accepted", false)) std::printf("refused: %s\n", f.value("reason", "").c_str());
}

// The guided sequence on a terminal: start, then per marker jog (typed here or with rbx1 jog elsewhere) and record,
// then fit, show the figures, and save on the operator's word. End of input or "q" cancels.
int guided(const Options& o) {
  nlohmann::json res;
  int rc = run_daemon_request(o.socket, o.json, calib_request("start"), &res, false);
  if (rc != 0) return rc;
  std::printf("%zu markers seen at the scan pose:", res["markers"].size());
  for (const auto& m : res["markers"]) std::printf(" %d", m["id"].get<int>());
  std::printf("\nFor each marker: jog the tool point onto its centre, then press Enter to record it.\n"
              "Type \"DX DY DZ\" (mm) to jog the tool point from here, \"s\" to skip the marker, \"f\" to fit now, "
              "\"q\" to cancel (the old calibration stays).\n");
  auto cancel = [&] {
    run_daemon_request(o.socket, o.json, calib_request("cancel"), nullptr, false);
    std::printf("cancelled; the old calibration stays in force\n");
    return 1;
  };
  std::vector<int> ids;
  for (const auto& m : res["markers"]) ids.push_back(m["id"].get<int>());
  bool fit_now = false;
  for (size_t i = 0; i < ids.size() && !fit_now;) {
    std::printf("marker %d> ", ids[i]);
    std::fflush(stdout);
    std::string line;
    if (!std::getline(std::cin, line) || line == "q") return cancel();
    if (line == "s") {
      ++i;
      continue;
    }
    if (line == "f") {
      fit_now = true;
      continue;
    }
    if (line.empty()) {
      nlohmann::json rec;
      if (run_daemon_request(o.socket, o.json, calib_request("record", ids[i]), &rec, false) == 0) {
        std::printf("recorded marker %d at %s mm\n", ids[i], rec["mm"].dump().c_str());
        ++i;
      }
      continue;
    }
    std::istringstream in(line);
    daemon::Request jog;
    jog.command = daemon::Command::Jog;
    if (!(in >> jog.mm[0] >> jog.mm[1] >> jog.mm[2])) {
      std::printf("type DX DY DZ in mm, Enter, s, f or q\n");
      continue;
    }
    nlohmann::json j;
    if (run_daemon_request(o.socket, o.json, jog, &j, false) == 0) std::printf("tool at %s\n", j["tool"].dump().c_str());
  }
  nlohmann::json fit;
  if (run_daemon_request(o.socket, o.json, calib_request("fit"), &fit, false) != 0) return cancel();
  print_fit(fit);
  if (!fit.value("accepted", false)) return cancel();
  std::printf("save this calibration? [y/N] ");
  std::fflush(stdout);
  std::string line;
  if (!std::getline(std::cin, line) || (line != "y" && line != "Y")) return cancel();
  nlohmann::json saved;
  rc = run_daemon_request(o.socket, o.json, calib_request("save"), &saved, false);
  if (rc == 0) std::printf("saved %s; scans now use it\n", saved.value("saved", "").c_str());
  return rc;
}

}  // namespace

void add_operator_commands(CLI::App& app, int& exit_code) {
  auto o = std::make_shared<Options>();
  o->socket = default_socket();

  CLI::App* jog = add(app, o, "jog", "move one joint by steps or degrees, or the tool point by millimetres (yaw kept)");
  jog->add_option("--joint", o->joint, "the joint's number, from 1")->check(CLI::Range(1, RBX1_JOINTS));
  auto* steps = jog->add_option("--steps", o->steps, "relative motor steps");
  auto* deg = jog->add_option("--deg", o->deg, "relative degrees");
  auto* mm = jog->add_option("--mm", o->mm, "tool point DX DY DZ in mm (base frame)")->expected(3);
  steps->excludes(deg);
  mm->excludes(steps)->excludes(deg);
  jog->callback([o, &exit_code, jog] {
    daemon::Request r;
    r.command = daemon::Command::Jog;
    if (!o->mm.empty()) {
      if (jog->count("--joint")) {
        std::fprintf(stderr, "rbx1: jog: --mm moves the tool point; it takes no --joint\n");
        exit_code = 2;
        return;
      }
      for (int i = 0; i < 3; ++i) r.mm[i] = o->mm[i];
    } else if (o->joint == 0 || (!jog->count("--steps") && !jog->count("--deg"))) {
      std::fprintf(stderr, "rbx1: jog: give --joint N with --steps S or --deg D, or --mm DX DY DZ\n");
      exit_code = 2;
      return;
    } else {
      r.joint = o->joint;
      r.by_steps = jog->count("--steps") > 0;
      r.steps = o->steps;
      r.deg = o->deg;
    }
    exit_code = run_daemon_request(o->socket, o->json, r);
  });

  CLI::App* pose = app.add_subcommand("pose", "teach the scan pose: rbx1 pose save scan");
  pose->require_subcommand(1);
  CLI::App* pose_save = add(*pose, o, "save", "store the arm's current pose as the scan pose");
  pose_save->add_option("name", o->name, "the pose (scan)")->required();
  pose_save->callback([o, &exit_code] {
    daemon::Request r;
    r.command = daemon::Command::PoseSave;
    r.name = o->name;
    exit_code = run_daemon_request(o->socket, o->json, r);
  });

  CLI::App* place = app.add_subcommand("place", "teach a place: rbx1 place save NAME");
  place->require_subcommand(1);
  CLI::App* place_save = add(*place, o, "save", "store the tool point (on the surface) and yaw as a named place");
  place_save->add_option("name", o->name, "the place's name")->required();
  place_save->callback([o, &exit_code] {
    daemon::Request r;
    r.command = daemon::Command::PlaceSave;
    r.name = o->name;
    exit_code = run_daemon_request(o->socket, o->json, r);
  });

  CLI::App* bg = add(app, o, "background", "capture the empty table at the scan pose; later scans subtract it");
  bg->add_option("--frames", o->frames, "frames to average (default [operator] background_frames)")->check(CLI::Range(1, 64));
  bg->callback([o, &exit_code] {
    daemon::Request r;
    r.command = daemon::Command::Background;
    r.frames = o->frames;
    exit_code = run_daemon_request(o->socket, o->json, r);
  });

  CLI::App* cw = add(app, o, "calibrate-workspace",
                     "map camera pixels to the arm's base frame from touched ArUco markers (guided when no ACTION)");
  cw->add_option("action", o->action, "start | status | record MARKER | fit | save | cancel (none: the guided sequence)")
      ->check(CLI::IsMember({"start", "status", "record", "fit", "save", "cancel"}));
  cw->add_option("marker", o->marker, "record: the marker id whose centre the tool point is on");
  cw->callback([o, &exit_code] {
    if (o->action.empty()) {
      exit_code = guided(*o);
      return;
    }
    if ((o->action == "record") != (o->marker >= 0)) {
      std::fprintf(stderr, "rbx1: calibrate-workspace: a marker id goes with record, and only with it\n");
      exit_code = 2;
      return;
    }
    nlohmann::json res;
    exit_code = run_daemon_request(o->socket, o->json, calib_request(o->action, std::max(0, o->marker)), &res,
                                   o->action != "fit" && o->action != "save");
    if (exit_code == 0 && !o->json && (o->action == "fit" || o->action == "save")) {
      print_fit(res);
      if (res.contains("saved")) std::printf("saved: %s\n", res["saved"].get<std::string>().c_str());
    }
  });

  auto sheet = std::make_shared<calib::SheetOptions>();
  auto out = std::make_shared<std::string>();
  CLI::App* mk = app.add_subcommand("markers", "write a printable sheet of ArUco markers at true scale (PDF or PNG)");
  mk->add_option("--out", *out, "FILE.pdf or FILE.png")->required();
  mk->add_option("--ids", sheet->ids, "marker ids (default 0 1 2 3 4 5)");
  mk->add_option("--marker-mm", sheet->marker_mm, "side of the black square in mm (default 40)");
  mk->add_option("--dictionary", sheet->dictionary, "ArUco dictionary (default 4X4_50; = [operator] marker_dictionary)");
  mk->add_option("--dpi", sheet->dpi, "PNG resolution (default 300)");
  mk->callback([sheet, out, &exit_code] {
    std::string error;
    auto ends = [&](const char* ext) {
      return out->size() >= 4 && out->compare(out->size() - 4, 4, ext) == 0;
    };
    bool ok;
    if (ends(".pdf")) ok = calib::write_marker_sheet_pdf(*out, *sheet, error);
    else if (ends(".png")) ok = calib::write_marker_sheet_png(*out, *sheet, error);
    else {
      ok = false;
      error = *out + ": the sheet is written as .pdf or .png";
    }
    if (!ok) {
      std::fprintf(stderr, "rbx1: markers: %s\n", error.c_str());
      exit_code = 2;
      return;
    }
    std::printf("wrote %s: %zu markers of %g mm (%s); print at 100 %%, check the 100 mm bar\n", out->c_str(),
                sheet->ids.size(), sheet->marker_mm, sheet->dictionary.c_str());
  });
}

}  // namespace rbx1::cli
