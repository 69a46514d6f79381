// console.cpp - the web console's HTTP routes: token rule, JSON requests through the socket's handler, event
// stream, pictures, static page.
#include "console.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <mutex>
#include <thread>
#include <type_traits>

#include <httplib.h>
#include <spdlog/spdlog.h>

#include "access.hpp"
#include "command_table.hpp"
#include "error_codes.hpp"
#include "event_hub.hpp"
#include "live_view.hpp"
#include "request.hpp"
#include "www_files.hpp"

namespace rbx1::console {

namespace {
constexpr int kThreads = 32;     // HTTP worker threads
constexpr int kMaxStreams = 24;  // event and live streams at once: the rest of the pool stays free for requests
constexpr auto kStreamPoll = std::chrono::milliseconds(1000);
// A jog still running after kHoldAfter streams its reply: a space every kPresencePoll until the final line (JSON
// allows leading white space). A write that fails means the page or client went away: the jog's dead-man STOP.
constexpr auto kHoldAfter = std::chrono::milliseconds(300);
// A page whose last event stream closed counts as open this long: the page replaces its stream (connectEvents() on
// a token change closes one and opens the next), and a jog of that page must not stop in between (e2e_console:
// "the page of a jog went away" in the same millisecond as the jog's request). A page that is gone stops its jog
// this much later.
constexpr auto kPageReconnectGrace = std::chrono::milliseconds(1000);
constexpr auto kPresencePoll = std::chrono::milliseconds(50);
// A page names itself (?page=ID on its event stream, X-RBX1-Page on its requests): its jogs last while that stream
// is open. A browser closing the tab drops the stream; the jog's own request it may keep reading to the end.
constexpr auto kEventKeepAlive = std::chrono::milliseconds(250);

using json = nlohmann::json;

using daemon::ErrorCode;

// An error body: the code from the one list (error_codes.hpp), never a string of the console's own.
json error_json(ErrorCode code, const std::string& message) { return daemon::error_reply({code, message}); }
static_assert(!std::is_invocable_v<decltype(&error_json), const char*, const std::string&>,
              "a console error's code is an ErrorCode: a mistyped code must not compile");

void send_json(httplib::Response& res, int status, const json& body) {
  res.status = status;
  res.set_content(body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
}

int http_status_for(const json& final_line) {
  if (final_line.contains("result")) return 200;
  std::string code = final_line["error"].value("code", "");
  if (daemon::is_request_error(code)) return 400;  // the request itself (error_codes.hpp)
  if (code == daemon::code_name(ErrorCode::ShuttingDown)) return 503;
  return 409;  // the arm could not do it now (busy, not_ready, estop, object_absent, ...)
}

// Libraries the pages use, from Debian's packages on the disk: never fetched from a network.
struct DebianJs {
  const char* url;
  const char* path;
  const char* package;
};
constexpr DebianJs kDebianJs[] = {
    {"/chart.js", "/usr/share/javascript/chart.js/chart.min.js", "libjs-chart.js"},  // the history page
    {"/three.js", "/usr/share/javascript/three/three.min.js", "libjs-three"},      // the 3D view
    {"/three-orbit.js", "/usr/share/javascript/three/examples/js/controls/OrbitControls.js", "libjs-three"},
};

std::string read_file(const char* path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// The commands the request layer knows that a console may call (command_table.hpp: all but the socket-only ones).
json known_commands() {
  json out = json::array();
  for (const auto& c : daemon::command_table())
    if (c.access != daemon::Access::Local) out.push_back(c.name);
  return out;
}

// The token class of POST /api/<cmd>, from the command table (an unknown command is refused after the token check).
Kind kind_of(const std::string& cmd) {
  const daemon::CommandSpec* spec = daemon::find_command(cmd);
  if (!spec) return Kind::Act;
  switch (spec->access) {
    case daemon::Access::Read: return Kind::Read;
    case daemon::Access::Estop: return Kind::Estop;
    default: return Kind::Act;
  }
}

// One request's lines, collected until its final line.
struct Exchange {
  std::mutex mutex;
  std::condition_variable cv;
  json events = json::array();
  json final_line;
  json started;           // a long job's started event (CommandSpec::started_event)
  bool done = false;
  bool answered = false;  // the HTTP reply went: later lines are not kept
};

// Counts open streams; refuses beyond kMaxStreams.
class StreamSlot {
 public:
  explicit StreamSlot(std::atomic<int>& count) : count_(count) { ok_ = ++count_ <= kMaxStreams; }
  ~StreamSlot() { --count_; }
  bool ok() const { return ok_; }

 private:
  std::atomic<int>& count_;
  bool ok_;
};
}  // namespace

struct Console::Impl {
  ConsoleConfig config;
  Submit submit;
  double job_timeout_s;
  httplib::Server http;
  EventHub hub;
  LiveView live;
  std::thread thread;
  std::atomic<bool> listen_returned{false};
  std::atomic<int> streams{0};
  std::shared_ptr<daemon::Subscription> bus_events;  // every client's requests, for the event log
  std::thread bus_thread;
  int port = 0;
  json info;
  std::string scans_dir;  // the history's scan images ("" = none)
  std::mutex pages_mutex;
  struct PageStreams {
    int open = 0;
    std::chrono::steady_clock::time_point closed_at;  // when the last one closed (open == 0)
  };
  std::map<std::string, PageStreams> pages;  // page id -> its event streams

  // Counts one open event stream of a page while it lives.
  struct PageStream {
    PageStream(Impl& impl, std::string id) : impl_(impl), id_(std::move(id)) {
      std::lock_guard lock(impl_.pages_mutex);
      const auto now = std::chrono::steady_clock::now();
      for (auto it = impl_.pages.begin(); it != impl_.pages.end();)  // pages gone for good
        it = it->second.open == 0 && now - it->second.closed_at >= kPageReconnectGrace ? impl_.pages.erase(it)
                                                                                        : std::next(it);
      ++impl_.pages[id_].open;
    }
    ~PageStream() {
      std::lock_guard lock(impl_.pages_mutex);
      PageStreams& p = impl_.pages[id_];
      if (--p.open <= 0) p.open = 0, p.closed_at = std::chrono::steady_clock::now();
    }
    Impl& impl_;
    std::string id_;
  };
  bool page_open(const std::string& id) {
    std::lock_guard lock(pages_mutex);
    auto it = pages.find(id);
    if (it == pages.end()) return false;
    return it->second.open > 0 || std::chrono::steady_clock::now() - it->second.closed_at < kPageReconnectGrace;
  }
  static bool valid_page_id(const std::string& id) {
    return !id.empty() && id.size() <= 64 &&
           id.find_first_not_of("0123456789abcdefABCDEF-") == std::string::npos;
  }

  Impl(ConsoleConfig c, Submit s, camera::FrameSource* camera, double timeout)
      : config(std::move(c)), submit(std::move(s)), job_timeout_s(timeout), live(camera, config.live_fps, config.jpeg_quality) {}

  // The token rule and, for POST, the cross-site guard. false after writing the refusal.
  bool allowed(const httplib::Request& req, httplib::Response& res, Kind kind) {
    if (token_required(kind, !config.token.empty(), config.loopback)) {
      std::string given = presented_token(req.get_header_value("Authorization"), req.get_param_value("token"));
      if (given.empty()) {
        send_json(res, 401, error_json(ErrorCode::Unauthorized, "this request needs the console token (Authorization: Bearer TOKEN)"));
        return false;
      }
      if (!token_matches(config.token, given)) {
        send_json(res, 401, error_json(ErrorCode::Unauthorized, "wrong console token"));
        return false;
      }
    }
    if (req.method == "POST") {
      // A JSON body and a same-origin page: another site's form or script cannot drive the arm through a browser.
      if (req.get_header_value("Content-Type").rfind("application/json", 0) != 0) {
        send_json(res, 415, error_json(ErrorCode::BadRequest, "the body must be JSON (Content-Type: application/json)"));
        return false;
      }
      std::string origin = req.get_header_value("Origin");
      if (!origin.empty() && origin != "http://" + req.get_header_value("Host")) {
        send_json(res, 403, error_json(ErrorCode::BadOrigin, "requests from another site's page (" + origin.substr(0, 80) + ") are refused"));
        return false;
      }
    }
    return true;
  }

  // The socket's request layer: the same parse_request, the same handler, one Reply whose lines come here.
  void run_request(const std::string& line, httplib::Response& res, const std::string& page = "") {
    daemon::Request request;
    daemon::Error err;
    if (!daemon::parse_request(line, request, err)) {
      send_json(res, 400, daemon::error_reply(err));
      return;
    }
    const daemon::CommandSpec& spec = daemon::command_spec(request.command);
    if (spec.access == daemon::Access::Local) {
      send_json(res, 403, error_json(ErrorCode::NotAllowed, std::string(spec.name) + " is not available from the console (the Unix socket only)"));
      return;
    }
    if (request.command == daemon::Command::Subscribe) {
      send_json(res, 400, error_json(ErrorCode::BadRequest, std::string(spec.name) + ": use GET /api/events for the bus"));
      return;
    }
    if (spec.access != daemon::Access::Read) spdlog::info("console: request {}", daemon::request_json(request).dump());
    auto ex = std::make_shared<Exchange>();
    auto present = std::make_shared<std::atomic<bool>>(true);
    const bool watch_page = valid_page_id(page) && page_open(page);
    // Called with the reply's lock held: only stores, never waits. The event log gets the lines from the bus.
    const std::string started_event = spec.started_event ? spec.started_event : "";
    daemon::Reply::Sink sink = [ex, started_event](const std::string& line, bool final_line) {
      json l = json::parse(line, nullptr, false);
      std::lock_guard lock(ex->mutex);
      if (ex->answered) return;  // a long job answered when it started: the rest is the event stream's
      if (final_line) {
        ex->final_line = l;
        ex->done = true;
        ex->cv.notify_all();
      } else {
        ex->events.push_back(l);
        if (!started_event.empty() && l.is_object() && l.value("event", "") == started_event) {
          ex->started = l;
          ex->cv.notify_all();
        }
      }
    };
    const bool dead_man = request.command == daemon::Command::Jog;
    daemon::Reply::Presence presence;
    if (dead_man)
      presence = [this, present, watch_page, page] {
        if (!present->load()) return false;
        if (watch_page && !page_open(page)) {
          spdlog::warn("console: the page of a jog went away mid-move (its event stream closed)");
          present->store(false);
          return false;
        }
        return true;
      };
    auto reply = std::make_shared<daemon::Reply>(sink, request.command, presence);
    const uint64_t req_id = reply->id();
    submit(request, std::move(reply));
    std::unique_lock lock(ex->mutex);
    const auto deadline = std::chrono::steady_clock::now() +
                          std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                              std::chrono::duration<double>(job_timeout_s + 30));
    // A sort or clear runs until the table is done, longer than an HTTP request should wait: 202 once it started
    // (its "req" names its lines on GET /api/events); a refusal before it starts keeps its status code.
    if (!started_event.empty() && ex->cv.wait_until(lock, deadline, [&] { return ex->done || !ex->started.is_null(); }) &&
        !ex->done) {
      ex->answered = true;
      return send_json(res, 202, {{"started", ex->started}, {"req", req_id}, {"events", std::move(ex->events)}});
    }
    if (dead_man && !ex->cv.wait_for(lock, kHoldAfter, [&] { return ex->done; })) {
      // Still moving: answer 200 now and stream, so that a client gone mid-move is seen by the failing write. Not
      // reusable: a browser leaving the page would otherwise read the rest to keep the connection, and stay.
      res.status = 200;
      res.set_header("Connection", "close");
      res.set_chunked_content_provider("application/json", [ex, present](size_t, httplib::DataSink& out) {
        std::unique_lock l(ex->mutex);
        if (!ex->cv.wait_for(l, kPresencePoll, [&] { return ex->done; })) {
          l.unlock();
          if (out.write(" ", 1)) return true;
          present->store(false);
          spdlog::warn("console: the client of a jog went away mid-move");
          return false;
        }
        json body = ex->final_line;
        body["events"] = ex->events;
        std::string text = body.dump(-1, ' ', false, json::error_handler_t::replace);
        l.unlock();
        out.write(text.data(), text.size());
        out.done();
        return true;
      });
      return;
    }
    if (!ex->cv.wait_until(lock, deadline, [&] { return ex->done; })) {
      send_json(res, 504, error_json(ErrorCode::Timeout, "no final reply within " + std::to_string(int(job_timeout_s + 30)) +
                                                    " s; the job goes on (see the event log)"));
      return;
    }
    json body = ex->final_line;
    body["events"] = ex->events;
    send_json(res, http_status_for(ex->final_line), body);
  }

  void history(const httplib::Request& req, httplib::Response& res) {
    json r{{"cmd", "history"}};
    for (const char* k : {"limit", "job"})
      if (req.has_param(k)) r[k] = std::atoll(req.get_param_value(k).c_str());
    for (const char* k : {"since", "format"})
      if (req.has_param(k)) r[k] = req.get_param_value(k);
    if (r.value("format", "") != "csv") return run_request(r.dump(), res);
    daemon::Request request;
    daemon::Error err;
    if (!daemon::parse_request(r.dump(), request, err)) return send_json(res, 400, daemon::error_reply(err));
    auto q = daemon::submit(submit, request);
    std::vector<json> events;
    json final;
    if (!q->wait_final(events, final, 10000)) return send_json(res, 504, error_json(ErrorCode::Timeout, "no history within 10 s"));
    if (!final.contains("result")) return send_json(res, http_status_for(final), final);
    res.set_content(final["result"].value("csv", ""), "text/csv");
  }

  void routes() {
    http.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
      std::string what = "internal error";
      try {
        std::rethrow_exception(ep);
      } catch (const std::exception& e) {
        what = e.what();
      } catch (...) {
      }
      send_json(res, 500, error_json(ErrorCode::Internal, what));
    });
    http.set_error_handler(httplib::Server::HandlerWithResponse([](const httplib::Request& req, httplib::Response& res) {
      if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
      if (res.status == 404) send_json(res, 404, error_json(ErrorCode::NotFound, "no such page or endpoint: " + req.path.substr(0, 80)));
      else if (res.status == 413) send_json(res, 413, error_json(ErrorCode::LineTooLong, "request body longer than " + std::to_string(daemon::kMaxRequestLine) + " bytes"));
      else send_json(res, res.status, error_json(ErrorCode::BadRequest, "HTTP " + std::to_string(res.status)));
      return httplib::Server::HandlerResponse::Handled;
    }));

    for (size_t i = 0; i < kWwwFileCount; ++i) {
      const WwwFile& f = kWwwFiles[i];
      http.Get(f.path, [&f](const httplib::Request&, httplib::Response& res) {
        res.set_header("Cache-Control", "no-cache");
        res.set_content(reinterpret_cast<const char*>(f.data), f.size, f.type);
      });
    }
    http.Get("/", [](const httplib::Request&, httplib::Response& res) { res.set_redirect("/index.html"); });

    http.Get("/api/status", [this](const httplib::Request& req, httplib::Response& res) {
      if (allowed(req, res, Kind::Read)) run_request(R"({"cmd":"status"})", res);
    });
    http.Get("/api/recipes", [this](const httplib::Request& req, httplib::Response& res) {
      if (allowed(req, res, Kind::Read)) run_request(R"({"cmd":"recipes"})", res);
    });
    http.Post(R"(/api/([a-z_]{1,40}))", [this](const httplib::Request& req, httplib::Response& res) {
      std::string cmd = req.matches[1];
      if (!allowed(req, res, kind_of(cmd))) return;
      json body = req.body.empty() ? json::object() : json::parse(req.body, nullptr, false);
      if (body.is_discarded()) return send_json(res, 400, error_json(ErrorCode::BadJson, "request body is not valid JSON"));
      if (!body.is_object()) return send_json(res, 400, error_json(ErrorCode::BadRequest, "request body must be a JSON object"));
      if (body.contains("cmd")) return send_json(res, 400, error_json(ErrorCode::BadField, "\"cmd\" comes from the URL, not the body"));
      body["cmd"] = cmd;
      run_request(body.dump(), res, req.get_header_value("X-RBX1-Page"));
    });

    http.Get("/api/info", [this](const httplib::Request& req, httplib::Response& res) {
      if (allowed(req, res, Kind::Read)) send_json(res, 200, info);
    });
    for (const DebianJs& lib : kDebianJs)
      http.Get(lib.url, [&lib](const httplib::Request&, httplib::Response& res) {
        std::string js = read_file(lib.path);  // the page caches it a day
        if (js.empty())
          return send_json(res, 404, error_json(ErrorCode::NotFound, std::string(lib.path) + ": missing (apt install " + lib.package + ")"));
        res.set_header("Cache-Control", "max-age=86400");
        res.set_content(js, "text/javascript; charset=utf-8");
      });
    // The 3D view's world (the scene request): the URDF, table, places, camera view, the last scan's objects.
    http.Get("/api/scene", [this](const httplib::Request& req, httplib::Response& res) {
      if (allowed(req, res, Kind::Read)) run_request(R"({"cmd":"scene"})", res);
    });
    // A pick's scan as the history kept it (404 no_image once the image budget removed it).
    http.Get(R"(/api/history/scan/(\d{1,18})\.jpg)", [this](const httplib::Request& req, httplib::Response& res) {
      if (!allowed(req, res, Kind::Read)) return;
      std::string jpeg = scans_dir.empty() ? "" : read_file((scans_dir + "/" + std::string(req.matches[1]) + ".jpg").c_str());
      if (jpeg.empty()) return send_json(res, 404, error_json(ErrorCode::NoImage, "no image kept for this scan ([history] max_mb)"));
      res.set_content(jpeg, "image/jpeg");
    });
    // The jobs' history (rbx1 history): JSON, or the picks as CSV with ?format=csv.
    http.Get("/api/history", [this](const httplib::Request& req, httplib::Response& res) {
      if (allowed(req, res, Kind::Read)) history(req, res);
    });
    http.Get("/api/scan", [this](const httplib::Request& req, httplib::Response& res) {
      if (!allowed(req, res, Kind::Read)) return;
      send_json(res, 200, {{"scans", live.scan_count()}, {"detections", live.scan_detections()}});
    });
    http.Get(R"(/api/scan\.(jpg|png))", [this](const httplib::Request& req, httplib::Response& res) {
      if (!allowed(req, res, Kind::Read)) return;
      res.set_header("Cache-Control", "no-store");
      if (req.matches[1] == "png") {
        std::string png;
        if (!live.scan_png(png)) return send_json(res, 404, error_json(ErrorCode::NoScan, "no scan yet: run a scan first"));
        return res.set_content(png, "image/png");
      }
      Jpeg jpeg;
      if (!live.scan_jpeg(jpeg)) return send_json(res, 404, error_json(ErrorCode::NoScan, "no scan yet: run a scan first"));
      res.set_content(*jpeg, "image/jpeg");
    });
    http.Get("/api/frame.jpg", [this](const httplib::Request& req, httplib::Response& res) {
      if (!allowed(req, res, Kind::Read)) return;
      Jpeg jpeg;
      std::string error;
      if (!live.grab_once(jpeg, error)) return send_json(res, 503, error_json(ErrorCode::CameraFailed, error));
      res.set_header("Cache-Control", "no-store");
      res.set_content(*jpeg, "image/jpeg");
    });
    http.Get("/api/live/stats", [this](const httplib::Request& req, httplib::Response& res) {
      if (!allowed(req, res, Kind::Read)) return;
      LiveStats s = live.stats();
      send_json(res, 200, {{"frames", s.frames}, {"grab_cpu_ns", s.grab_cpu_ns}, {"encode_cpu_ns", s.encode_cpu_ns},
                           {"failures", s.failures}, {"viewers", s.viewers}, {"streams", streams.load()},
                           {"live_fps", config.live_fps}});
    });
    http.Get("/api/live.mjpg", [this](const httplib::Request& req, httplib::Response& res) {
      if (!allowed(req, res, Kind::Read)) return;
      auto slot = std::make_shared<StreamSlot>(streams);
      if (!slot->ok()) return send_json(res, 503, error_json(ErrorCode::TooManyStreams, "too many live views and event streams open"));
      auto viewer = std::make_shared<LiveView::Viewer>(live);
      res.set_header("Cache-Control", "no-store");
      res.set_chunked_content_provider(
          "multipart/x-mixed-replace; boundary=rbx1frame",
          [this, slot, viewer](size_t, httplib::DataSink& sink) {
            Jpeg jpeg;
            if (!viewer->next(jpeg, kStreamPoll)) {
              if (hub.closed()) {
                sink.done();
                return true;
              }
              return sink.is_writable();
            }
            std::string head = "--rbx1frame\r\nContent-Type: image/jpeg\r\nContent-Length: " +
                               std::to_string(jpeg->size()) + "\r\n\r\n";
            return sink.write(head.data(), head.size()) && sink.write(jpeg->data(), jpeg->size()) &&
                   sink.write("\r\n", 2);
          });
    });
    http.Get("/api/events", [this](const httplib::Request& req, httplib::Response& res) {
      if (!allowed(req, res, Kind::Read)) return;
      auto slot = std::make_shared<StreamSlot>(streams);
      if (!slot->ok()) return send_json(res, 503, error_json(ErrorCode::TooManyStreams, "too many live views and event streams open"));
      uint64_t after = 0;
      std::string last = req.get_header_value("Last-Event-ID");
      if (last.empty()) last = req.get_param_value("after");
      if (!last.empty() && last.size() < 20 && last.find_first_not_of("0123456789") == std::string::npos)
        after = std::stoull(last);
      auto cursor = std::make_shared<uint64_t>(after);
      auto status_seen = std::make_shared<uint64_t>(0);
      std::string page = req.get_param_value("page");
      auto page_stream = valid_page_id(page) ? std::make_shared<PageStream>(*this, page) : nullptr;
      res.set_header("Cache-Control", "no-store");
      res.set_chunked_content_provider("text/event-stream", [this, slot, cursor, status_seen, page_stream](size_t, httplib::DataSink& sink) {
        std::string status;
        auto events = hub.wait(*cursor, *status_seen, status, page_stream ? kEventKeepAlive : kStreamPoll);
        if (hub.closed()) {
          sink.done();
          return true;
        }
        // The arm's status as a named event: the log's onmessage never sees it, and it has no id (no replay).
        std::string out = status.empty() ? "" : "event: status\ndata: " + status + "\n\n";
        for (const auto& e : events) {
          out += "id: " + std::to_string(e.seq) + "\ndata: " + e.data + "\n\n";
          *cursor = e.seq;
        }
        if (out.empty()) out = ": keep-alive\n\n";  // also finds a client that went away
        return sink.write(out.data(), out.size());
      });
    });
  }
};

Console::Console(ConsoleConfig config, Submit submit, daemon::Bus& bus, camera::FrameSource* camera,
                 double job_timeout_s, nlohmann::json info)
    : impl_(std::make_unique<Impl>(std::move(config), std::move(submit), camera, job_timeout_s)) {
  impl_->info = std::move(info);
  impl_->info["commands"] = known_commands();
  impl_->bus_events = bus.subscribe(unsigned(daemon::Topic::Events) | unsigned(daemon::Topic::Status), 1024);
}

Console::~Console() { stop(); }

void Console::serve_scans(std::string dir) { impl_->scans_dir = std::move(dir); }

int Console::start(std::string& error) {
  Impl& m = *impl_;
  m.http.new_task_queue = [] { return new httplib::ThreadPool(kThreads); };
  m.http.set_payload_max_length(daemon::kMaxRequestLine);
  m.http.set_keep_alive_timeout(5);
  m.routes();
  // SO_REUSEADDR only: cpp-httplib's default also sets SO_REUSEPORT, with which a second daemon binds the same port
  // and the kernel shares the connections between them (a browser could drive the other arm). A restart still
  // binds at once over the old connections' TIME_WAIT.
  m.http.set_socket_options([](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });
  std::string host = m.config.host == "localhost" ? "127.0.0.1" : m.config.host;
  if (m.config.port == 0) {
    m.port = m.http.bind_to_any_port(host);
  } else {
    m.port = m.http.bind_to_port(host, m.config.port) ? m.config.port : -1;
  }
  if (m.port <= 0) {
    int e = errno ? errno : EADDRINUSE;
    error = "console: cannot listen on " + m.config.bind + ": " + std::strerror(e);
    return -e;
  }
  m.thread = std::thread([&m] {
    m.http.listen_after_bind();
    m.listen_returned = true;
  });
  m.bus_thread = std::thread([&m] {  // the bus's request lines into the event log, as they come
    daemon::BusMessage msg;
    while (!m.bus_events->closed())
      if (m.bus_events->next(msg, 500)) {
        json e = *msg.body;
        e.erase("topic");
        e.erase("seq");
        if (msg.topic == daemon::Topic::Status) m.hub.set_status(e);
        else m.hub.publish(std::move(e));
      }
  });
  // httplib's stop() shuts only a listener already running: a stop right after start would be lost and the join in
  // stop() would wait for ever. Start returns once it runs.
  while (!m.http.is_running() && !m.listen_returned) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  return 0;
}

void Console::stop() {
  Impl& m = *impl_;
  m.bus_events->close();
  if (m.bus_thread.joinable()) m.bus_thread.join();
  m.hub.close();  // ends the event and live streams
  m.live.stop();
  m.http.stop();
  if (m.thread.joinable()) m.thread.join();
}

int Console::port() const { return impl_->port; }

std::string Console::url() const {
  const auto& c = impl_->config;
  std::string host = c.host.find(':') != std::string::npos ? "[" + c.host + "]" : c.host;
  return "http://" + host + ":" + std::to_string(impl_->port) + "/";
}

void Console::scan_done(const cv::Mat& annotated, const nlohmann::json& detections) {
  impl_->live.set_scan(annotated, detections);
  impl_->hub.publish({{"scan", impl_->live.scan_count()}, {"objects", detections.value("objects", json::array()).size()}});
}

}  // namespace rbx1::console
