// main.cpp - rbx1-world: runs rbx1-simfw as its arm, serves the end-effector camera's frames and the world's state
// on a Unix socket, and applies the firmware's executed queue entries to the objects (tools/world/README.md).
#include <CLI/CLI.hpp>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "camera_view.hpp"
#include "world_state.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

bool write_atomic(const std::string& path, const std::string& text) {
  std::string tmp = path + ".tmp." + std::to_string(::getpid());
  {
    std::ofstream f(tmp, std::ios::trunc);
    f << text;
    f.flush();
    if (!f) return false;
  }
  return std::rename(tmp.c_str(), path.c_str()) == 0;
}

// The calibration a user makes with `rbx1 calibrate` for this camera: its lens (intrinsics, distortion) and the
// nominal table scale at the scan pose (host/calib/README.md, version 1).
json calibration_json(const rbx1::world::Scene& s) {
  using namespace rbx1::world;
  Eigen::Isometry3d pose = camera_pose(s.nominal.links, s.nominal_camera, s.nominal.scan);
  const Camera& c = s.nominal_camera;
  Eigen::Vector2d o = pixel_on_table(c, pose, 0, 0), px = pixel_on_table(c, pose, 1000, 0);
  double px_per_cm = 1000.0 / ((px - o).norm() / 10.0);
  return {{"format", "rbx1-calibration"}, {"version", 1},
          {"homography", {{1 / px_per_cm, 0, 0}, {0, 1 / px_per_cm, 0}, {0, 0, 1}}},
          {"camera_matrix", {{c.fx, 0, c.cx}, {0, c.fy, c.cy}, {0, 0, 1}}},
          {"dist_coeffs", c.dist},
          {"image_size", {c.width, c.height}}};
}

// The [arm.camera] mapping of the nominal camera at the scan pose (host/arm/README.md "Camera to arm").
json arm_camera_json(const rbx1::world::Scene& s) {
  using namespace rbx1::world;
  Eigen::Isometry3d pose = camera_pose(s.nominal.links, s.nominal_camera, s.nominal.scan);
  const Camera& c = s.nominal_camera;
  Eigen::Vector2d o = pixel_on_table(c, pose, 0, 0), ex = pixel_on_table(c, pose, 100, 0) - o,
                  ey = pixel_on_table(c, pose, 0, 100) - o;
  bool flip = ex.x() * ey.y() - ex.y() * ey.x() < 0;
  double rot = std::atan2(ex.y(), ex.x()) * 180 / 3.14159265358979323846;
  return {{"origin_mm", {std::round(o.x() * 1000) / 1000, std::round(o.y() * 1000) / 1000}},
          {"rotation_deg", std::round(rot * 1000) / 1000}, {"flip_y", flip}};
}

// The table corners seen by a camera at the scan pose (pixel corners through the pinhole, mm, clockwise on screen).
json view_json(const rbx1::world::Scene& s, const rbx1::arm::Links& links, const rbx1::world::Camera& c) {
  using namespace rbx1::world;
  Eigen::Isometry3d pose = camera_pose(links, c, s.nominal.scan);
  json out = json::array();
  for (auto [u, v] : {std::pair{0.0, 0.0}, {c.width - 1.0, 0.0}, {c.width - 1.0, c.height - 1.0}, {0.0, c.height - 1.0}}) {
    Eigen::Vector2d p = pixel_on_table(c, pose, u, v);
    out.push_back({std::round(p.x() * 100) / 100, std::round(p.y() * 100) / 100});
  }
  return out;
}

int listen_unix(const std::string& path, std::string& error) {
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  if (path.size() >= sizeof(a.sun_path)) {
    error = path + ": path too long for a Unix socket";
    return -1;
  }
  std::strcpy(a.sun_path, path.c_str());
  int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  ::unlink(path.c_str());
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) != 0 || ::listen(fd, 8) != 0) {
    error = path + ": " + std::strerror(errno);
    if (fd >= 0) ::close(fd);
    return -1;
  }
  return fd;
}

bool send_all(int fd, const char* p, size_t n) {
  while (n > 0) {
    ssize_t k = ::send(fd, p, n, MSG_NOSIGNAL);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) {
      if (errno != EAGAIN) return false;
      pollfd pfd{fd, POLLOUT, 0};
      if (::poll(&pfd, 1, 5000) <= 0) return false;
      continue;
    }
    p += k;
    n -= size_t(k);
  }
  return true;
}

struct Simfw {
  pid_t pid = -1;
  int log_fd = -1;
  std::string port;
};

// Starts rbx1-simfw with its move log on a pipe (fd 3 in the child) and reads the pty path it prints.
bool start_simfw(const std::string& exe, double time_scale, Simfw& out, std::string& error) {
  int log_pipe[2], out_pipe[2];
  if (::pipe2(log_pipe, O_CLOEXEC) != 0 || ::pipe2(out_pipe, O_CLOEXEC) != 0) {
    error = std::string("pipe: ") + std::strerror(errno);
    return false;
  }
  pid_t pid = ::fork();
  if (pid < 0) {
    error = std::string("fork: ") + std::strerror(errno);
    return false;
  }
  if (pid == 0) {
    ::dup2(log_pipe[1], 3);
    ::dup2(out_pipe[1], 1);
    ::fcntl(3, F_SETFD, 0);  // dup2 onto itself would keep close-on-exec
    ::fcntl(1, F_SETFD, 0);
    std::string scale = std::to_string(time_scale);
    ::execl(exe.c_str(), exe.c_str(), "--log-moves", "/dev/fd/3", "--time-scale", scale.c_str(), nullptr);
    std::fprintf(stderr, "rbx1-world: %s: %s\n", exe.c_str(), std::strerror(errno));
    ::_exit(127);
  }
  ::close(log_pipe[1]);
  ::close(out_pipe[1]);
  std::string line;
  char c;
  while (::read(out_pipe[0], &c, 1) == 1 && c != '\n') line += c;
  ::close(out_pipe[0]);
  if (line.empty()) {
    error = exe + ": printed no pty path";
    ::kill(pid, SIGTERM);
    ::waitpid(pid, nullptr, 0);
    return false;
  }
  out.pid = pid;
  out.log_fd = log_pipe[0];
  out.port = line;
  ::fcntl(out.log_fd, F_SETFL, O_NONBLOCK);
  return true;
}

// "light GAIN OFFSET": the steady light from now on (Light::gain, offset). Returns the reply line.
std::string light_request(rbx1::world::World& world, const std::string& args) {
  double gain = 0, offset = 0;
  char extra = 0;
  if (std::sscanf(args.c_str(), "%lf %lf %c", &gain, &offset, &extra) != 2)
    return "error light: give GAIN OFFSET, e.g. \"light 0.8 -10\"\n";
  std::string err;
  return world.set_light(gain, offset, err) ? "ok\n" : "error " + err + "\n";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rbx1-world: a simulated table, objects, camera and gripper around rbx1-simfw"};
  std::string scene_path, simfw, dir, events_path, state_path, calibration_out, snapshot;
  uint64_t seed = 0;
  double time_scale = 8.0;
  app.add_option("--scene", scene_path, "the scene file (tools/world/README.md)")->required();
  app.add_option("--seed", seed, "overrides the scene's seed (errors drawn, noise)");
  app.add_option("--simfw", simfw, "the simulated firmware (default: rbx1-simfw beside this program)");
  app.add_option("--time-scale", time_scale, "simulated seconds per wall second for rbx1-simfw")
      ->check(CLI::Range(0.1, 50.0));
  app.add_option("--dir", dir, "folder for the camera socket (default: a new /tmp/rbx1-world-XXXXXX)");
  app.add_option("--events", events_path, "append one JSON line per event (grasp, collision, placement, ...)");
  app.add_option("--state", state_path, "write the final state (JSON) here on exit");
  app.add_option("--write-calibration", calibration_out,
                 "write the lens + nominal scale calibration for rbx1d's [vision] calibration, print the nominal "
                 "[arm.camera] mapping as JSON, and exit");
  app.add_option("--snapshot", snapshot, "write the frame seen at the scan pose to this PNG and exit");
  bool view = false;
  app.add_flag("--view", view,
               "print the table corners (mm) seen by the true and the nominal camera at the scan pose as JSON, and exit");
  CLI11_PARSE(app, argc, argv);

  rbx1::world::Scene scene;
  std::string error;
  std::optional<uint64_t> seed_override;
  if (app.count("--seed")) seed_override = seed;
  if (!rbx1::world::load_scene(scene_path, scene, error, seed_override)) {
    std::cerr << "rbx1-world: " << error << "\n";
    return 2;
  }
  if (!calibration_out.empty()) {
    if (!write_atomic(calibration_out, calibration_json(scene).dump(1) + "\n")) {
      std::cerr << "rbx1-world: " << calibration_out << ": cannot write\n";
      return 2;
    }
    std::cout << json{{"arm_camera", arm_camera_json(scene)}}.dump() << "\n";
    return 0;
  }
  if (view) {
    std::cout << json{{"true_view_mm", view_json(scene, scene.links, scene.camera)},
                      {"nominal_view_mm", view_json(scene, scene.nominal.links, scene.nominal_camera)}}.dump()
              << "\n";
    return 0;
  }
  if (!snapshot.empty()) {
    auto pose = rbx1::world::camera_pose(scene.links, scene.camera, scene.nominal.scan);
    if (!cv::imwrite(snapshot, rbx1::world::render_frame(scene, pose, 0))) {
      std::cerr << "rbx1-world: " << snapshot << ": cannot write\n";
      return 2;
    }
    return 0;
  }

  if (simfw.empty()) simfw = (fs::path(fs::canonical("/proc/self/exe")).parent_path() / "rbx1-simfw").string();
  bool own_dir = dir.empty();
  if (own_dir) {
    char tmpl[] = "/tmp/rbx1-world-XXXXXX";
    if (!::mkdtemp(tmpl)) {
      std::cerr << "rbx1-world: mkdtemp: " << std::strerror(errno) << "\n";
      return 1;
    }
    dir = tmpl;
  }
  std::string sock_path = (fs::path(dir) / "camera.sock").string();
  int listen_fd = listen_unix(sock_path, error);
  if (listen_fd < 0) {
    std::cerr << "rbx1-world: " << error << "\n";
    return 1;
  }
  FILE* events = nullptr;
  if (!events_path.empty() && !(events = std::fopen(events_path.c_str(), "a"))) {
    std::cerr << "rbx1-world: " << events_path << ": " << std::strerror(errno) << "\n";
    return 1;
  }

  struct sigaction sa{};
  sa.sa_handler = on_signal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  Simfw sim;
  if (!start_simfw(simfw, time_scale, sim, error)) {
    std::cerr << "rbx1-world: " << error << "\n";
    return 1;
  }
  std::printf("unix:%s\n%s\n", sock_path.c_str(), sim.port.c_str());
  std::fflush(stdout);

  rbx1::world::World world(scene);
  world.on_event([events](const json& ev) {
    std::fprintf(stderr, "rbx1-world: %s\n", ev.dump().c_str());
    if (events) {
      std::fprintf(events, "%s\n", ev.dump().c_str());
      std::fflush(events);
    }
  });

  std::string log_buf;
  auto drain_log = [&]() -> bool {  // false when the firmware's end of the pipe closed
    char buf[4096];
    for (;;) {
      ssize_t n = ::read(sim.log_fd, buf, sizeof(buf));
      if (n > 0) {
        log_buf.append(buf, size_t(n));
        continue;
      }
      if (n == 0) return false;
      break;
    }
    size_t pos;
    while ((pos = log_buf.find('\n')) != std::string::npos) {
      std::string line = log_buf.substr(0, pos);
      log_buf.erase(0, pos + 1);
      std::string err;
      if (!world.apply_log_line(line, err)) std::fprintf(stderr, "rbx1-world: %s\n", err.c_str());
    }
    return true;
  };

  std::map<int, std::string> clients;  // fd -> pending request bytes
  uint64_t frames = 0;
  int status = 0;
  bool log_open = true;
  while (!g_stop) {
    std::vector<pollfd> fds{{listen_fd, POLLIN, 0}};
    if (log_open) fds.push_back({sim.log_fd, POLLIN, 0});
    for (const auto& [fd, _] : clients) fds.push_back({fd, POLLIN, 0});
    const size_t first_client = fds.size() - clients.size();
    if (::poll(fds.data(), fds.size(), 200) < 0 && errno != EINTR) break;
    if (log_open && !drain_log()) log_open = false;
    int ws;
    if (::waitpid(sim.pid, &ws, WNOHANG) == sim.pid) {
      std::fprintf(stderr, "rbx1-world: rbx1-simfw exited (%d)\n", WIFEXITED(ws) ? WEXITSTATUS(ws) : -1);
      sim.pid = -1;
      status = 1;
      break;
    }
    if (fds[0].revents & POLLIN) {
      int c = ::accept4(listen_fd, nullptr, nullptr, SOCK_CLOEXEC);
      if (c >= 0) clients[c] = "";
    }
    for (size_t i = first_client; i < fds.size(); ++i) {
      if (!fds[i].revents) continue;
      int fd = fds[i].fd;
      char buf[256];
      ssize_t n = ::recv(fd, buf, sizeof(buf), 0);
      if (n <= 0) {
        ::close(fd);
        clients.erase(fd);
        continue;
      }
      std::string& pending = clients[fd];
      pending.append(buf, size_t(n));
      size_t pos;
      bool ok = true;
      while (ok && (pos = pending.find('\n')) != std::string::npos) {
        std::string req = pending.substr(0, pos);
        pending.erase(0, pos + 1);
        if (log_open) drain_log();  // entries completed before the request are in the pipe: apply them first
        if (req == "frame") {
          auto pose = rbx1::world::camera_pose(scene.links, scene.camera, world.joints());
          cv::Mat img = rbx1::world::render_frame(world.scene(), pose, frames++);
          std::string head = "frame " + std::to_string(img.cols) + " " + std::to_string(img.rows) + "\n";
          ok = send_all(fd, head.data(), head.size()) &&
               send_all(fd, reinterpret_cast<const char*>(img.data), img.total() * 3);
        } else if (req == "state") {
          json s = world.state();
          s["frames"] = frames;
          std::string text = s.dump() + "\n";
          ok = send_all(fd, text.data(), text.size());
        } else if (req == "markers on" || req == "markers off") {
          std::string err;
          std::string text = world.set_markers_on_table(req == "markers on", err) ? "ok\n" : "error " + err + "\n";
          ok = send_all(fd, text.data(), text.size());
        } else if (req == "table clear" || req == "table objects") {
          std::string err;
          std::string text = world.set_table_cleared(req == "table clear", err) ? "ok\n" : "error " + err + "\n";
          ok = send_all(fd, text.data(), text.size());
        } else if (req.rfind("light ", 0) == 0) {
          std::string text = light_request(world, req.substr(6));
          ok = send_all(fd, text.data(), text.size());
        } else {
          std::string text = "error unknown request \"" + req +
                             "\" (frame, state, markers on, markers off, table clear, table objects, light G O)\n";
          ok = send_all(fd, text.data(), text.size());
        }
      }
      if (!ok) {
        ::close(fd);
        clients.erase(fd);
      }
    }
  }
  if (sim.pid > 0) {
    ::kill(sim.pid, SIGTERM);
    ::waitpid(sim.pid, nullptr, 0);
  }
  if (log_open) drain_log();
  if (!state_path.empty()) {
    json s = world.state();
    s["frames"] = frames;
    if (!write_atomic(state_path, s.dump(1) + "\n")) {
      std::cerr << "rbx1-world: " << state_path << ": cannot write\n";
      status = 1;
    }
  }
  for (const auto& [fd, _] : clients) ::close(fd);
  ::close(listen_fd);
  ::unlink(sock_path.c_str());
  if (own_dir) ::rmdir(dir.c_str());
  if (events) std::fclose(events);
  return status;
}
