// console_test.cpp - the web console's config, token rule, event ring, and its HTTP layer in-process: every
// refused request (token, body, origin, size) reaches nothing; accepted ones reach the handler once, parsed.
#include <gtest/gtest.h>

#include <httplib.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <iterator>
#include <thread>

#include "access.hpp"
#include "console.hpp"
#include "console_config.hpp"
#include "event_hub.hpp"

using namespace rbx1::console;
using nlohmann::json;

namespace {
ConsoleConfig parse(const std::string& toml, rbx1::config::Errors& errors) {
  toml::table root = rbx1::config::parse_text(toml, errors);
  rbx1::config::Section top(&root, "", errors);
  ConsoleConfig c;
  parse_console_config(top.section("console"), c);
  return c;
}
std::string errors_text(const rbx1::config::Errors& e) {
  std::string s;
  for (const auto& m : e.messages()) s += m + "\n";
  return s;
}
}  // namespace

TEST(ConsoleConfig, Defaults) {
  rbx1::config::Errors errors;
  ConsoleConfig c = parse("", errors);
  ASSERT_TRUE(errors.ok()) << errors_text(errors);
  EXPECT_EQ(c.bind, "127.0.0.1:8080");
  EXPECT_EQ(c.host, "127.0.0.1");
  EXPECT_EQ(c.port, 8080);
  EXPECT_TRUE(c.loopback);
  EXPECT_TRUE(c.token.empty());
}

TEST(ConsoleConfig, NonLoopbackNeedsToken) {
  rbx1::config::Errors errors;
  parse("[console]\nbind = \"0.0.0.0:8080\"\n", errors);
  ASSERT_EQ(errors.messages().size(), 1u) << errors_text(errors);
  EXPECT_NE(errors.messages()[0].find("console.token: must be set when the console listens beyond loopback (console.bind \"0.0.0.0:8080\")"),
            std::string::npos) << errors_text(errors);
  rbx1::config::Errors ok;
  ConsoleConfig c = parse("[console]\nbind = \"0.0.0.0:8080\"\ntoken = \"0123456789abcdef\"\n", ok);
  EXPECT_TRUE(ok.ok()) << errors_text(ok);
  EXPECT_FALSE(c.loopback);
  // --console replaces the file's bind with the same checks.
  rbx1::config::Errors over;
  ConsoleConfig d = parse("", over);
  override_console_bind("192.168.1.5:8080", d, over);
  ASSERT_EQ(over.messages().size(), 1u) << errors_text(over);
  EXPECT_EQ(over.messages()[0].rfind("console.token: must be set when the console listens beyond loopback (--console", 0), 0u)
      << errors_text(over);
  rbx1::config::Errors bad;
  override_console_bind("nowhere", d, bad);
  ASSERT_EQ(bad.messages().size(), 1u);
  EXPECT_EQ(bad.messages()[0].rfind("--console: must be \"HOST:PORT\"", 0), 0u) << errors_text(bad);
  rbx1::config::Errors fine;
  override_console_bind("127.0.0.1:0", d, fine);
  EXPECT_TRUE(fine.ok());
  EXPECT_EQ(d.port, 0);
}

TEST(ConsoleConfig, BadValuesNameTheirKey) {
  const char* cases[][2] = {
      {"bind = \"8080\"", "console.bind"},          {"bind = \"127.0.0.1:99999\"", "console.bind"},
      {"bind = \"example.org:80\"", "console.bind"}, {"bind = \"::1:80\"", "console.bind"},
      {"token = \"short\"", "console.token"},        {"token = \"has a space in it ....\"", "console.token"},
      {"live_fps = 0", "console.live_fps"},          {"jpeg_quality = 101", "console.jpeg_quality"},
      {"bindd = \"x\"", "console.bindd"},
  };
  for (auto& c : cases) {
    rbx1::config::Errors errors;
    parse(std::string("[console]\n") + c[0] + "\n", errors);
    ASSERT_EQ(errors.messages().size(), 1u) << c[0] << "\n" << errors_text(errors);
    EXPECT_EQ(errors.messages()[0].rfind(c[1], 0), 0u) << errors_text(errors);
  }
}

TEST(ConsoleConfig, BindForms) {
  std::string host, error;
  int port = -1;
  ASSERT_TRUE(parse_bind("[::1]:8081", host, port, error)) << error;
  EXPECT_EQ(host, "::1");
  EXPECT_EQ(port, 8081);
  EXPECT_TRUE(is_loopback_host(host));
  ASSERT_TRUE(parse_bind("localhost:0", host, port, error)) << error;
  EXPECT_EQ(port, 0);
  EXPECT_TRUE(is_loopback_host("127.4.5.6"));
  EXPECT_FALSE(is_loopback_host("128.0.0.1"));
  EXPECT_FALSE(is_loopback_host("::"));
}

TEST(Access, TokenRule) {
  // No token: loopback only, nothing needs one.
  for (Kind k : {Kind::Page, Kind::Read, Kind::Estop, Kind::Act}) EXPECT_FALSE(token_required(k, false, true));
  // Token on loopback: only what acts.
  EXPECT_TRUE(token_required(Kind::Act, true, true));
  EXPECT_FALSE(token_required(Kind::Estop, true, true));
  EXPECT_FALSE(token_required(Kind::Read, true, true));
  // Beyond loopback: everything but the page.
  EXPECT_TRUE(token_required(Kind::Act, true, false));
  EXPECT_TRUE(token_required(Kind::Estop, true, false));
  EXPECT_TRUE(token_required(Kind::Read, true, false));
  EXPECT_FALSE(token_required(Kind::Page, true, false));
  EXPECT_EQ(presented_token("Bearer abc", "q"), "abc");
  EXPECT_EQ(presented_token("", "q"), "q");
  EXPECT_TRUE(token_matches("0123456789abcdef", "0123456789abcdef"));
  EXPECT_FALSE(token_matches("0123456789abcdef", "0123456789abcdeg"));
  EXPECT_FALSE(token_matches("0123456789abcdef", "0123456789abcde"));
  EXPECT_FALSE(token_matches("", ""));
}

TEST(EventHub, OrderedRingAndWaiters) {
  EventHub hub(3);
  for (int i = 0; i < 5; ++i) hub.publish({{"n", i}});
  auto all = hub.wait(0, std::chrono::milliseconds(0));
  ASSERT_EQ(all.size(), 3u);  // the ring keeps the last three
  EXPECT_EQ(all[0].seq, 3u);
  EXPECT_EQ(json::parse(all[2].data)["n"], 4);
  EXPECT_TRUE(hub.wait(5, std::chrono::milliseconds(10)).empty());
  std::thread t([&] { hub.publish({{"n", 5}}); });
  auto next = hub.wait(5, std::chrono::seconds(5));
  t.join();
  ASSERT_EQ(next.size(), 1u);
  EXPECT_EQ(next[0].seq, 6u);
  hub.close();
  EXPECT_TRUE(hub.wait(0, std::chrono::seconds(5)).empty());
}

TEST(EventHub, TheLatestStatusBesideTheRing) {
  EventHub hub(3);
  uint64_t seen = 0;
  std::string status;
  EXPECT_TRUE(hub.wait(0, seen, status, std::chrono::milliseconds(10)).empty());
  EXPECT_EQ(status, "");
  hub.set_status({{"n", 1}});
  hub.set_status({{"n", 2}});
  EXPECT_TRUE(hub.wait(0, seen, status, std::chrono::seconds(5)).empty());
  EXPECT_EQ(status, R"({"n":2})");  // only the newest is kept
  EXPECT_TRUE(hub.wait(0, seen, status, std::chrono::milliseconds(10)).empty());
  EXPECT_EQ(status, "");              // nothing new since
  EXPECT_EQ(hub.last_seq(), 0u);      // not an event of the log
  std::thread t([&] { hub.set_status({{"n", 3}}); });
  hub.wait(0, seen, status, std::chrono::seconds(5));  // a waiter wakes for a new status
  t.join();
  EXPECT_EQ(status, R"({"n":3})");
}

// ---- the HTTP layer against a recording handler ----------------------------------------------------------------

namespace {
const char* kToken = "0123456789abcdef0123";

struct Fixture {
  std::vector<rbx1::daemon::Request> seen;
  std::shared_ptr<rbx1::daemon::Reply> held;  // a sort's reply, still open
  std::mutex mutex;
  rbx1::daemon::Bus bus;
  std::unique_ptr<rbx1::camera::FrameSource> camera;
  std::unique_ptr<Console> console;
  std::unique_ptr<httplib::Client> client;

  explicit Fixture(const std::string& token) {
    std::string error;
    rbx1::camera::CameraConfig cam;
    cam.device = RBX1_DATA_DIR "/demo/scene.png";
    camera = rbx1::camera::open_source(cam, error);
    EXPECT_TRUE(camera) << error;
    ConsoleConfig cfg;
    cfg.bind = "127.0.0.1:0";
    cfg.port = 0;
    cfg.token = token;
    console = std::make_unique<Console>(
        cfg,
        [this](const rbx1::daemon::Request& r, std::shared_ptr<rbx1::daemon::Reply> reply) {
          {
            std::lock_guard lock(mutex);
            seen.push_back(r);
          }
          // As rbx1d's handler does: every request but reads on the bus, which the event log follows.
          if (r.command != rbx1::daemon::Command::Status) reply->publish_to(bus, rbx1::daemon::request_json(r));
          reply->event("working", {{"n", 1}});
          if (r.command == rbx1::daemon::Command::Sort) {  // a long job: started, then runs until the test ends it
            reply->event("sort_started", {{"job", 7}, {"kind", "sort"}});
            std::lock_guard lock(mutex);
            held = reply;
            return;
          }
          if (r.command == rbx1::daemon::Command::Clear) return reply->error("unknown_place", "no place \"moon\"");
          if (r.command == rbx1::daemon::Command::Home) reply->error("not_ready", "the arm is not ready");
          else reply->result({{"cmd", rbx1::daemon::command_name(r.command)}, {"name", r.name}});
        },
        bus, camera.get(), 5, json{{"places", {"tray"}}});
    EXPECT_EQ(console->start(error), 0) << error;
    client = std::make_unique<httplib::Client>("127.0.0.1", console->port());
  }
  size_t count() {
    std::lock_guard lock(mutex);
    return seen.size();
  }
  httplib::Result post(const std::string& path, const std::string& body, httplib::Headers h = {},
                       const char* type = "application/json") {
    return client->Post(path.c_str(), h, body, type);
  }
};

json body(const httplib::Result& r) { return json::parse(r->body); }
httplib::Headers bearer(const std::string& t) { return {{"Authorization", "Bearer " + t}}; }
}  // namespace

TEST(ConsoleHttp, TokenRefusalsReachNothing) {
  Fixture f(kToken);
  auto r = f.post("/api/pick", R"({"name":"star","place":"tray"})");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 401);
  EXPECT_EQ(body(r)["error"]["code"], "unauthorized");
  EXPECT_NE(body(r)["error"]["message"].get<std::string>().find("needs the console token"), std::string::npos);
  r = f.post("/api/pick", R"({"name":"star","place":"tray"})", bearer("0123456789abcdef0124"));
  EXPECT_EQ(r->status, 401);
  EXPECT_EQ(body(r)["error"]["message"], "wrong console token");
  r = f.post("/api/home?token=nope", "{}");
  EXPECT_EQ(r->status, 401);
  EXPECT_EQ(f.count(), 0u);
  // The right token, as a header and as the query parameter.
  r = f.post("/api/pick", R"({"name":"star","place":"tray"})", bearer(kToken));
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(body(r)["result"]["name"], "star");
  EXPECT_EQ(body(r)["events"].size(), 1u);
  EXPECT_EQ(body(r)["events"][0]["event"], "working");
  r = f.post(std::string("/api/scan?token=") + kToken, "");
  EXPECT_EQ(r->status, 200) << r->body;
  // On loopback the e-stop and reading need no token.
  r = f.post("/api/estop", "{}");
  EXPECT_EQ(r->status, 200) << r->body;
  auto g = f.client->Get("/api/status");
  EXPECT_EQ(g->status, 200);
  ASSERT_EQ(f.count(), 4u);
  EXPECT_EQ(f.seen[0].command, rbx1::daemon::Command::Pick);
  EXPECT_EQ(f.seen[0].place, "tray");
  EXPECT_EQ(f.seen[2].command, rbx1::daemon::Command::Estop);
}

TEST(ConsoleHttp, MalformedRequestsGetClearErrorsAndReachNothing) {
  Fixture f("");
  struct Case {
    std::string path, body;
    int status;
    std::string code;
  } cases[] = {
      {"/api/pick", "{\"name\":", 400, "bad_json"},
      {"/api/pick", "[1,2]", 400, "bad_request"},
      {"/api/pick", R"({"name":"star"})", 400, "missing_field"},
      {"/api/pick", R"({"name":"star","place":7})", 400, "bad_field"},
      {"/api/pick", R"({"cmd":"home","name":"star","place":"tray"})", 400, "bad_field"},
      {"/api/home", R"({"speed":9})", 400, "bad_field"},
      {"/api/fly", "{}", 400, "unknown_command"},
      {"/api/shutdown", "{}", 403, "not_allowed"},
      {"/api/pick", "{\"name\":\"" + std::string(5000, 'x') + "\"}", 413, "line_too_long"},
      {"/api/Pick!", "{}", 404, "not_found"},
  };
  for (const auto& c : cases) {
    auto r = f.post(c.path, c.body);
    ASSERT_TRUE(r) << c.path;
    EXPECT_EQ(r->status, c.status) << c.path << " " << c.body.substr(0, 60) << " -> " << r->body;
    EXPECT_EQ(body(r)["error"]["code"], c.code) << r->body;
    EXPECT_FALSE(body(r)["error"]["message"].get<std::string>().empty());
  }
  auto r = f.post("/api/home", "{}", {}, "text/plain");
  EXPECT_EQ(r->status, 415);
  r = f.post("/api/home", "{}", {{"Origin", "http://evil.example"}});
  EXPECT_EQ(r->status, 403);
  EXPECT_EQ(body(r)["error"]["code"], "bad_origin");
  EXPECT_EQ(f.count(), 0u);
  // A job error comes back as 409 with the daemon's own code.
  r = f.post("/api/home", "{}", {{"Origin", "http://127.0.0.1:" + std::to_string(f.console->port())}});
  EXPECT_EQ(r->status, 409) << r->body;
  EXPECT_EQ(body(r)["error"]["code"], "not_ready");
  EXPECT_EQ(f.count(), 1u);
}

TEST(ConsoleHttp, PageImagesAndEvents) {
  Fixture f("");
  auto r = f.client->Get("/index.html");
  ASSERT_EQ(r->status, 200);
  EXPECT_NE(r->body.find("id=\"estop\""), std::string::npos);
  EXPECT_EQ(f.client->Get("/console.js")->status, 200);
  r = f.client->Get("/api/scan.jpg");
  EXPECT_EQ(r->status, 404);
  EXPECT_EQ(body(r)["error"]["code"], "no_scan");
  cv::Mat annotated(48, 64, CV_8UC3, cv::Scalar(0, 0, 255));
  f.console->scan_done(annotated, {{"objects", json::array({{{"index", 1}}})}});
  r = f.client->Get("/api/scan.jpg");
  ASSERT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Type"), "image/jpeg");
  EXPECT_EQ(uint8_t(r->body[0]), 0xFF);  // JPEG SOI
  r = f.client->Get("/api/scan.png");
  ASSERT_EQ(r->status, 200);
  EXPECT_EQ(r->body.substr(1, 3), "PNG");
  r = f.client->Get("/api/scan");
  EXPECT_EQ(body(r)["scans"], 1);
  EXPECT_EQ(body(r)["detections"]["objects"][0]["index"], 1);
  r = f.client->Get("/api/frame.jpg");
  ASSERT_EQ(r->status, 200);
  EXPECT_GT(r->body.size(), 1000u);
  json info = body(f.client->Get("/api/info"));
  EXPECT_EQ(info["places"][0], "tray");
  for (const char* c : {"scan", "pick", "home", "estop", "clear_fault"})  // the socket's commands, seen by the page
    EXPECT_NE(std::find(info["commands"].begin(), info["commands"].end(), c), info["commands"].end()) << c << " " << info.dump();
  // The event stream replays what is kept: the scan, then a pick's request, event and result in order.
  ASSERT_EQ(f.post("/api/pick", R"({"name":"star","place":"tray"})")->status, 200);
  std::string stream;
  httplib::Client sse("127.0.0.1", f.console->port());
  sse.Get("/api/events", [&](const char* data, size_t n) {
    stream.append(data, n);
    return stream.find("\"result\"") == std::string::npos;  // stop reading after the final line
  });
  size_t scan = stream.find("\"scan\":1"), req = stream.find("\"request\":{\"cmd\":\"pick\"");
  size_t ev = stream.find("\"event\":\"working\""), res = stream.find("\"result\":");
  ASSERT_NE(scan, std::string::npos) << stream;
  ASSERT_NE(req, std::string::npos) << stream;
  ASSERT_NE(ev, std::string::npos) << stream;
  ASSERT_NE(res, std::string::npos) << stream;
  EXPECT_LT(scan, req);
  EXPECT_LT(req, ev);
  EXPECT_LT(ev, res);
}

// The 3D view's parts: its files, three.js from Debian's libjs-three on the disk, the scene request, and the arm's
// status on the event stream as a named event (which the log's onmessage never sees).
TEST(ConsoleHttp, ThreeDViewPartsAndTheStatusOnTheEventStream) {
  Fixture f("");
  EXPECT_EQ(f.client->Get("/arm3d.js")->status, 200);
  EXPECT_EQ(f.client->Get("/arm3d.css")->status, 200);
  const char* const files[][2] = {
      {"/three.js", "/usr/share/javascript/three/three.min.js"},
      {"/three-orbit.js", "/usr/share/javascript/three/examples/js/controls/OrbitControls.js"}};
  for (const auto& [url, path] : files) {
    std::ifstream in(path, std::ios::binary);
    std::string debian((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_FALSE(debian.empty()) << path << " missing: apt install libjs-three (tools/install-deps)";
    auto r = f.client->Get(url);
    ASSERT_EQ(r->status, 200) << url;
    EXPECT_EQ(r->body, debian) << url;
  }
  auto r = f.client->Get("/api/scene");
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(body(r)["result"]["cmd"], "scene");
  f.bus.publish(rbx1::daemon::Topic::Status, {{"joints_deg", {1, 2, 3, 4, 5, 6}}});
  std::string stream;
  httplib::Client sse("127.0.0.1", f.console->port());
  const std::string want = "event: status\ndata: {\"joints_deg\":[1,2,3,4,5,6]}\n\n";
  sse.Get("/api/events", [&](const char* data, size_t n) {
    stream.append(data, n);
    return stream.find(want) == std::string::npos;
  });
  size_t at = stream.find(want);
  ASSERT_NE(at, std::string::npos) << stream;
  EXPECT_TRUE(at == 0 || stream.compare(at - 2, 2, "\n\n") == 0) << "a status has no id (no replay): " << stream;
}

// A sort runs until the table is done, far longer than an HTTP request may wait (the fixture's job_timeout_s is 5:
// it once answered 504 after job_timeout_s + 30 s): answered 202 as soon as it started, its progress and its end on
// the event stream; a sort or clear refused before it starts keeps its status code.
TEST(ConsoleHttp, ALongJobIsAnsweredWhenItStartsAndReportsOnTheEventStream) {
  Fixture f("");
  auto t0 = std::chrono::steady_clock::now();
  auto r = f.post("/api/sort", R"({"recipe":{"star":"tray"}})");
  double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  EXPECT_LT(waited, 5.0);
  json b = body(r);
  EXPECT_EQ(b["started"]["event"], "sort_started");
  EXPECT_EQ(b["started"]["job"], 7);
  EXPECT_FALSE(b.contains("result"));
  ASSERT_EQ(b["events"].size(), 2u) << b.dump();  // working, sort_started: what came before the answer
  std::shared_ptr<rbx1::daemon::Reply> held;
  {
    std::lock_guard lock(f.mutex);
    held = f.held;
  }
  ASSERT_TRUE(held);
  EXPECT_EQ(b["req"], held->id());
  held->event("progress", {{"job", 7}, {"phase", "pick"}, {"picked", 1}});
  held->result({{"job", 7}, {"outcome", "done"}, {"picked_total", 1}});
  // The event stream carries the sort's lines, named by its req, to the end.
  std::string stream;
  httplib::Client sse("127.0.0.1", f.console->port());
  sse.Get("/api/events", [&](const char* data, size_t n) {
    stream.append(data, n);
    return stream.find("\"outcome\":\"done\"") == std::string::npos;
  });
  std::string req = "\"req\":" + std::to_string(held->id());
  size_t started = stream.find("\"event\":\"sort_started\""), picked = stream.find("\"picked\":1");
  size_t done = stream.find("\"outcome\":\"done\"");
  ASSERT_NE(started, std::string::npos) << stream;
  ASSERT_NE(picked, std::string::npos) << stream;
  ASSERT_NE(done, std::string::npos) << stream;
  EXPECT_LT(started, picked);
  EXPECT_LT(picked, done);
  EXPECT_NE(stream.find(req), std::string::npos) << stream;
  // Refused before it starts: the daemon's code and status, at once.
  r = f.post("/api/clear", R"({"place":"moon"})");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 409) << r->body;
  EXPECT_EQ(body(r)["error"]["code"], "unknown_place");
  EXPECT_EQ(f.count(), 2u);
}

TEST(ConsoleHttp, NonLoopbackReadsNeedTheToken) {
  // The listener is on loopback here; the rule is the one for a LAN address (console_config sets loopback).
  std::string error;
  rbx1::camera::CameraConfig cam;
  cam.device = RBX1_DATA_DIR "/demo/scene.png";
  auto camera = rbx1::camera::open_source(cam, error);
  ConsoleConfig cfg;
  cfg.host = "127.0.0.1";
  cfg.port = 0;
  cfg.loopback = false;
  cfg.token = kToken;
  int calls = 0;
  rbx1::daemon::Bus bus;
  Console console(cfg, [&](const rbx1::daemon::Request&, std::shared_ptr<rbx1::daemon::Reply> r) { ++calls; r->result({}); },
                  bus, camera.get(), 5);
  ASSERT_EQ(console.start(error), 0) << error;
  httplib::Client c("127.0.0.1", console.port());
  EXPECT_EQ(c.Get("/api/status")->status, 401);
  EXPECT_EQ(c.Get("/api/scan.jpg")->status, 401);
  EXPECT_EQ(c.Get("/api/events")->status, 401);
  EXPECT_EQ(c.Post("/api/estop", "{}", "application/json")->status, 401);
  EXPECT_EQ(calls, 0);
  EXPECT_EQ(c.Get("/index.html")->status, 200);
  EXPECT_EQ(c.Get((std::string("/api/status?token=") + kToken).c_str())->status, 200);
  EXPECT_EQ(calls, 1);
}

TEST(ConsoleHttp, APortInUseIsRefusedNotShared) {
  // Two daemons on one port would share its connections: the second must fail to listen, saying why.
  std::string error;
  rbx1::camera::CameraConfig cam;
  cam.device = RBX1_DATA_DIR "/demo/scene.png";
  auto camera = rbx1::camera::open_source(cam, error);
  auto handler = [](const rbx1::daemon::Request&, std::shared_ptr<rbx1::daemon::Reply> r) { r->result({}); };
  ConsoleConfig cfg;
  cfg.bind = "127.0.0.1:0";
  cfg.host = "127.0.0.1";
  cfg.port = 0;
  rbx1::daemon::Bus bus;
  Console first(cfg, handler, bus, camera.get(), 5);
  ASSERT_EQ(first.start(error), 0) << error;
  cfg.port = first.port();
  cfg.bind = "127.0.0.1:" + std::to_string(first.port());
  Console second(cfg, handler, bus, camera.get(), 5);
  EXPECT_LT(second.start(error), 0);
  EXPECT_EQ(error, "console: cannot listen on " + cfg.bind + ": Address already in use");
}
