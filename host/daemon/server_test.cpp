// server_test.cpp - the control socket and the request layer: framing, limits, error replies, mode, stale sockets;
// clients that never read, idle and surplus connections, and the e-stop getting through all of them.
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "control_client.hpp"
#include "reply.hpp"
#include "request.hpp"
#include "server.hpp"

using namespace rbx1;
using namespace rbx1::daemon;
using Clock = std::chrono::steady_clock;

namespace {

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

// A Server on a temporary path, run on its own thread with a handler that answers at once: status with a 1 kB
// result (so that an unread connection fills quickly), scan with one event first, home after hold_ms from another
// thread (a job still open), estop counted.
class TestServer {
 public:
  explicit TestServer(const ServerLimits& limits = {}, int hold_ms = 0) : hold_ms_(hold_ms) {
    static std::atomic<int> n{0};
    path_ = "/tmp/rbx1-server-test-" + std::to_string(getpid()) + "-" + std::to_string(n++) + ".sock";
    std::string error;
    open_result_ = server_.open(path_, 0660, error);
    EXPECT_EQ(open_result_, 0) << error;
    server_.set_limits(limits);
    thread_ = std::thread([this] {
      server_.run([this](const Request& r, std::shared_ptr<Reply> reply) {
        ++handled_;
        if (r.command == Command::Estop) {
          ++estops_;
          estop_at_ = Clock::now().time_since_epoch().count();
        }
        if (r.command == Command::Scan) reply->event("step", {{"n", 1}});
        nlohmann::json result{{"cmd", command_name(r.command)}, {"name", r.name}};
        if (r.command == Command::Status) result["pad"] = std::string(1000, 'x');
        if (r.command == Command::Home && hold_ms_ > 0) {
          std::thread([reply, result, this] {
            std::this_thread::sleep_for(std::chrono::milliseconds(hold_ms_));
            reply->result(result);
          }).detach();
          return;
        }
        reply->result(result);
      });
    });
  }
  ~TestServer() {
    server_.stop();
    thread_.join();
    std::this_thread::sleep_for(std::chrono::milliseconds(hold_ms_));  // detached replies finish
  }
  const std::string& path() const { return path_; }
  int handled() const { return handled_; }
  int estops() const { return estops_; }
  int64_t estop_at() const { return estop_at_; }

 private:
  int hold_ms_;
  int open_result_ = -1;
  std::string path_;
  Server server_;
  std::thread thread_;
  std::atomic<int> handled_{0}, estops_{0};
  std::atomic<int64_t> estop_at_{0};
};

int connect_raw(const std::string& path) {
  int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// True when the daemon closed fd within timeout_ms (reads until end of stream, discarding what comes).
bool closed_within(int fd, int timeout_ms) {
  auto deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
  char buf[65536];
  while (Clock::now() < deadline) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n == 0 || (n < 0 && errno == ECONNRESET)) return true;
  }
  return false;
}

// A client that writes status requests as fast as the socket takes them and never reads a reply; when the daemon
// drops it, it counts the drop and (if asked) connects again.
class Flooder {
 public:
  Flooder(std::string path, bool reconnect) : path_(std::move(path)), reconnect_(reconnect) {
    thread_ = std::thread([this] { loop(); });
  }
  ~Flooder() {
    stop_ = true;
    thread_.join();
  }
  int drops() const { return drops_; }
  long sent() const { return sent_; }
  bool connected_once() const { return connected_; }

 private:
  void loop() {
    std::string burst;
    for (int i = 0; i < 64; ++i) burst += "{\"cmd\":\"status\"}\n";
    timeval tv{0, 50000};  // a blocked send returns now and then to look at stop_
    while (!stop_) {
      int fd = connect_raw(path_);
      if (fd < 0) {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
        continue;
      }
      connected_ = true;
      ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
      while (!stop_) {
        ssize_t n = ::send(fd, burst.data(), burst.size(), MSG_NOSIGNAL);
        if (n > 0) {
          sent_ += n;
          continue;
        }
        if (n < 0 && (errno == EAGAIN || errno == EINTR)) continue;
        ++drops_;
        break;
      }
      ::close(fd);
      if (!reconnect_) {
        while (!stop_) std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
    }
  }
  std::string path_;
  bool reconnect_;
  std::thread thread_;
  std::atomic<bool> stop_{false}, connected_{false};
  std::atomic<int> drops_{0};
  std::atomic<long> sent_{0};
};

nlohmann::json roundtrip(control::Client& c, const std::string& line, int timeout_ms = 2000) {
  EXPECT_EQ(c.send_line(line), 0);
  std::string reply;
  int r = c.read_line(reply, timeout_ms);
  EXPECT_EQ(r, 0) << "no reply to " << line << " within " << timeout_ms << " ms";
  if (r != 0) return nullptr;
  return nlohmann::json::parse(reply, nullptr, false);
}

// A request on a new connection; its final line within timeout_ms, or null. ms: the time to the final line.
nlohmann::json request_once(const std::string& path, const std::string& line, int timeout_ms, double* ms = nullptr) {
  control::Client c;
  std::string error;
  auto t0 = Clock::now();
  if (c.connect(path, error) < 0) {
    ADD_FAILURE() << error;
    return nullptr;
  }
  auto j = roundtrip(c, line, timeout_ms);
  if (ms) *ms = ms_since(t0);
  return j;
}

}  // namespace

TEST(Server, SocketModeIs0660) {
  TestServer s;
  struct stat st {};
  ASSERT_EQ(::stat(s.path().c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0660u);
}

TEST(Server, StreamsEventsThenOneFinalLine) {
  TestServer s;
  control::Client c;
  std::string error;
  ASSERT_EQ(c.connect(s.path(), error), 0) << error;
  Request r;
  r.command = Command::Scan;
  ASSERT_EQ(c.send(r), 0);
  std::string line;
  ASSERT_EQ(c.read_line(line, 2000), 0);
  auto ev = nlohmann::json::parse(line);
  EXPECT_EQ(ev["event"], "step");
  EXPECT_EQ(ev["n"], 1);
  EXPECT_TRUE(ev["ts"].is_string());
  EXPECT_TRUE(ev["t_ms"].is_number());
  EXPECT_FALSE(control::is_final(ev));
  ASSERT_EQ(c.read_line(line, 2000), 0);
  auto fin = nlohmann::json::parse(line);
  EXPECT_TRUE(control::is_final(fin));
  EXPECT_EQ(fin["result"]["cmd"], "scan");
}

TEST(Server, MalformedLinesGetErrorsAndTheConnectionSurvives) {
  TestServer s;
  control::Client c;
  std::string error;
  ASSERT_EQ(c.connect(s.path(), error), 0) << error;
  EXPECT_EQ(roundtrip(c, "not json")["error"]["code"], "bad_json");
  EXPECT_EQ(roundtrip(c, R"({"cmd":"fly"})")["error"]["code"], "unknown_command");
  EXPECT_EQ(roundtrip(c, R"({"cmd":"pick"})")["error"]["code"], "missing_field");
  EXPECT_EQ(roundtrip(c, std::string(100000, 'x'))["error"]["code"], "line_too_long");
  EXPECT_EQ(roundtrip(c, R"({"cmd":"pick","name":"bolt","place":"tray"})")["result"]["name"], "bolt");
  EXPECT_EQ(s.handled(), 1);
}

TEST(Server, ServesManyClientsConnectingAtOnce) {
  // Connections accepted while others are served must be polled from the next round on (a past bug read
  // their events from beyond the poll array and dropped them).
  TestServer s;
  std::vector<std::unique_ptr<control::Client>> clients;
  for (int i = 0; i < 20; ++i) {
    auto c = std::make_unique<control::Client>();
    std::string error;
    ASSERT_EQ(c->connect(s.path(), error), 0) << error;
    ASSERT_EQ(c->send_line(R"({"cmd":"home"})"), 0);
    clients.push_back(std::move(c));
  }
  for (auto& c : clients) {
    std::string line;
    ASSERT_EQ(c->read_line(line, 2000), 0);
    EXPECT_EQ(nlohmann::json::parse(line)["result"]["cmd"], "home");
  }
  EXPECT_EQ(s.handled(), 20);
}

TEST(Server, RefusesALiveSocket) {
  TestServer s;
  Server second;
  std::string error;
  EXPECT_EQ(second.open(s.path(), 0660, error), -EADDRINUSE);
  EXPECT_NE(error.find("another rbx1d"), std::string::npos) << error;
  EXPECT_EQ(request_once(s.path(), R"({"cmd":"home"})", 2000)["result"]["cmd"], "home");  // the first still serves
}

TEST(Server, ReplacesAStaleSocket) {
  // A socket file left by a crash: bound once, its owner gone, nobody listening.
  std::string path = "/tmp/rbx1-server-test-stale-" + std::to_string(getpid()) + ".sock";
  ::unlink(path.c_str());
  int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ::close(fd);
  ASSERT_EQ(::chmod(path.c_str(), 0600), 0);
  // A second name keeps the stale inode alive, so a replacement cannot reuse its number.
  std::string keep = path + ".old";
  ::unlink(keep.c_str());
  ASSERT_EQ(::link(path.c_str(), keep.c_str()), 0);
  struct stat before {};
  ASSERT_EQ(::stat(path.c_str(), &before), 0);
  ASSERT_TRUE(S_ISSOCK(before.st_mode));
  EXPECT_LT(connect_raw(path), 0) << "the stale socket must refuse connections before the test";

  Server server;
  std::string error;
  ASSERT_EQ(server.open(path, 0660, error), 0) << error;
  struct stat after {};
  ASSERT_EQ(::stat(path.c_str(), &after), 0);
  EXPECT_NE(after.st_ino, before.st_ino) << "the stale file was not replaced";
  EXPECT_EQ(after.st_mode & 0777, 0660u);
  std::thread t([&] { server.run([](const Request&, std::shared_ptr<Reply> r) { r->result({{"ok", true}}); }); });
  EXPECT_EQ(request_once(path, R"({"cmd":"status"})", 2000)["result"]["ok"], true);
  server.stop();
  t.join();
  ::unlink(keep.c_str());
}

TEST(Server, NotASocketIsRefused) {
  std::string path = "/tmp/rbx1-server-test-file-" + std::to_string(getpid());
  std::FILE* f = std::fopen(path.c_str(), "w");
  ASSERT_TRUE(f);
  std::fclose(f);
  Server server;
  std::string error;
  EXPECT_EQ(server.open(path, 0660, error), -EEXIST);
  EXPECT_NE(error.find("exists and is not a socket"), std::string::npos) << error;
  struct stat st {};
  EXPECT_EQ(::stat(path.c_str(), &st), 0) << "the file must be left alone";
  ::unlink(path.c_str());
}

// Defect: a client that writes and never reads stalled the socket (each of its replies waited up to 1 s for room),
// so other clients' status and estop timed out. Now its unread replies fill its own buffer and it is dropped.
TEST(Server, AClientThatNeverReadsStallsNobody) {
  TestServer s;
  Flooder flooder(s.path(), /*reconnect=*/false);
  for (int i = 0; i < 200 && flooder.sent() < 2000000 && !flooder.drops(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  double worst = 0;
  for (int i = 0; i < 20; ++i) {
    double ms = 0;
    auto st = request_once(s.path(), R"({"cmd":"status"})", 2000, &ms);
    ASSERT_TRUE(st.is_object()) << "status " << i << " got no reply within 2 s beside a client that never reads";
    EXPECT_EQ(st["result"]["cmd"], "status");
    worst = std::max(worst, ms);
  }
  double ms = 0;
  auto es = request_once(s.path(), R"({"cmd":"estop"})", 2000, &ms);
  ASSERT_TRUE(es.is_object()) << "estop got no reply within 2 s beside a client that never reads";
  EXPECT_EQ(es["result"]["cmd"], "estop");
  EXPECT_EQ(s.estops(), 1);
  for (int i = 0; i < 500 && !flooder.drops(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(flooder.drops(), 1) << "the client that never reads was not disconnected (sent " << flooder.sent() << " B)";
  std::printf("status beside a non-reading client: worst %.2f ms of 20; estop %.2f ms; the flooder sent %ld B\n",
              worst, ms, flooder.sent());
}

// Defect: 32 idle connections locked out the e-stop ("busy: too many control connections"). Now every new
// connection gets in (the least recently active one makes room beyond the limit), and an estop line is handled
// before any other request of its poll round: 100 idle and 10 flooding clients, then an e-stop.
TEST(Server, EstopGetsThroughAHundredIdleAndTenFloodingClients) {
  TestServer s;
  std::vector<int> idle;
  for (int i = 0; i < 100; ++i) {
    int fd = connect_raw(s.path());
    ASSERT_GE(fd, 0) << "idle connection " << i;
    idle.push_back(fd);
  }
  std::vector<std::unique_ptr<Flooder>> flooders;
  for (int i = 0; i < 10; ++i) flooders.push_back(std::make_unique<Flooder>(s.path(), /*reconnect=*/true));
  // The e-stops go in once the flood is at full strength: 4 MB sent and a flooder already dropped for not reading
  // (a deadline, not a wait time: a sanitizer build on a loaded machine floods 4 times slower).
  for (int i = 0; i < 3000; ++i) {
    long sent = 0;
    int drops = 0;
    for (auto& f : flooders) sent += f->sent(), drops += f->drops();
    if (sent > 4000000 && drops > 0) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::vector<double> latencies;
  for (int k = 0; k < 5; ++k) {
    int before = s.estops();
    auto t0 = Clock::now();
    double ms = 0;
    auto es = request_once(s.path(), R"({"cmd":"estop"})", 2000, &ms);
    ASSERT_TRUE(es.is_object()) << "estop " << k << " got no reply within 2 s";
    ASSERT_EQ(es["result"]["cmd"], "estop") << es.dump();
    ASSERT_EQ(s.estops(), before + 1);
    latencies.push_back(std::chrono::duration<double, std::milli>(Clock::duration(s.estop_at()) - t0.time_since_epoch()).count());
  }
  auto st = request_once(s.path(), R"({"cmd":"status"})", 2000);
  EXPECT_EQ(st["result"]["cmd"], "status");
  long sent = 0;
  int drops = 0;
  for (auto& f : flooders) {
    sent += f->sent();
    drops += f->drops();
    EXPECT_TRUE(f->connected_once());
  }
  EXPECT_GT(drops, 0) << "no flooding client was ever dropped";
  std::sort(latencies.begin(), latencies.end());
  std::printf("estop connect+send -> handler with 100 idle and 10 flooding clients: median %.2f ms, max %.2f ms "
              "(5 tries); flooders sent %ld B, dropped %d times\n",
              latencies[2], latencies[4], sent, drops);
  for (int fd : idle) ::close(fd);
}

TEST(Server, IdleConnectionsTimeOutButOpenRequestsDoNot) {
  ServerLimits limits;
  limits.idle_timeout_ms = 200;
  TestServer s(limits, /*hold_ms=*/600);
  int idle = connect_raw(s.path());
  ASSERT_GE(idle, 0);
  control::Client busy;
  std::string error;
  ASSERT_EQ(busy.connect(s.path(), error), 0) << error;
  ASSERT_EQ(busy.send_line(R"({"cmd":"home"})"), 0);  // answered after 600 ms: open for longer than the timeout
  auto t0 = Clock::now();
  EXPECT_TRUE(closed_within(idle, 3000)) << "an idle connection was not closed";
  double idle_ms = ms_since(t0);
  EXPECT_GE(idle_ms, 150) << "closed before the idle timeout";
  std::string line;
  ASSERT_EQ(busy.read_line(line, 3000), 0) << "a connection with an open request was closed";
  EXPECT_EQ(nlohmann::json::parse(line)["result"]["cmd"], "home");
  // Its request answered, it is idle in turn.
  EXPECT_EQ(busy.read_line(line, 3000), -ECONNRESET);
  ::close(idle);
}

TEST(Server, ASurplusConnectionMakesTheLeastRecentlyActiveOneLeave) {
  ServerLimits limits;
  limits.max_clients = 4;
  TestServer s(limits);
  std::vector<int> fds;
  for (int i = 0; i < 4; ++i) {
    fds.push_back(connect_raw(s.path()));
    ASSERT_GE(fds.back(), 0);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // Client 0 was active last (a request), so client 1 is now the least recently active.
  ASSERT_EQ(::send(fds[0], "{\"cmd\":\"scan\"}\n", 15, MSG_NOSIGNAL), 15);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  auto es = request_once(s.path(), R"({"cmd":"estop"})", 2000);
  EXPECT_EQ(es["result"]["cmd"], "estop") << es.dump();
  EXPECT_EQ(s.estops(), 1);
  // Client 1 was told why and closed; the others stay.
  char buf[4096];
  pollfd p{fds[1], POLLIN, 0};
  ASSERT_EQ(::poll(&p, 1, 2000), 1);
  ssize_t n = ::recv(fds[1], buf, sizeof buf - 1, 0);
  ASSERT_GT(n, 0);
  buf[n] = 0;
  EXPECT_NE(std::string(buf).find(R"("code":"busy")"), std::string::npos) << buf;
  EXPECT_TRUE(closed_within(fds[1], 2000));
  for (int i : {2, 3}) {
    pollfd q{fds[i], POLLIN, 0};
    EXPECT_EQ(::poll(&q, 1, 0), 0) << "client " << i << " was closed too";
  }
  for (int fd : fds) ::close(fd);
}

TEST(Server, EstopIsTakenBeforeTheRequestsQueuedAheadOfIt) {
  // One client sends 200 requests and an estop in one write: the estop is handled in the first round, before
  // the requests that wait their turn (16 a round).
  TestServer s;
  control::Client c;
  std::string error;
  ASSERT_EQ(c.connect(s.path(), error), 0) << error;
  std::string burst;
  for (int i = 0; i < 200; ++i) burst += "{\"cmd\":\"home\"}\n";
  burst += "{\"cmd\":\"estop\"}";
  ASSERT_EQ(c.send_line(burst), 0);
  std::vector<std::string> cmds;
  std::string line;
  while (cmds.size() < 201 && c.read_line(line, 2000) == 0) cmds.push_back(nlohmann::json::parse(line)["result"]["cmd"]);
  ASSERT_EQ(cmds.size(), 201u);
  auto at = std::find(cmds.begin(), cmds.end(), "estop") - cmds.begin();
  EXPECT_LE(at, 16) << "the estop waited behind " << at << " requests";
}

TEST(RequestLayer, InProcessSubmitGetsEventsThenTheFinalLine) {
  std::atomic<int> calls{0};
  Handler h = [&](const Request& r, std::shared_ptr<Reply> reply) {
    ++calls;
    std::thread([r, reply] {
      reply->event("step", {{"n", 1}});
      reply->event("step", {{"n", 2}});
      reply->result({{"cmd", command_name(r.command)}});
      reply->event("late", {});  // after the final line: dropped
    }).detach();
  };
  Request r;
  r.command = Command::Scan;
  auto q = submit(h, r);
  std::vector<nlohmann::json> events;
  nlohmann::json final;
  ASSERT_TRUE(q->wait_final(events, final, 2000));
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[1]["n"], 2);
  EXPECT_EQ(final["result"]["cmd"], "scan");
  EXPECT_TRUE(q->done());
  nlohmann::json more;
  EXPECT_FALSE(q->next(more, 100));

  // A malformed line never reaches the handler; its error is the reply.
  auto bad = std::make_shared<ReplyQueue>();
  EXPECT_FALSE(submit_line(h, R"({"cmd":"fly"})", ReplyQueue::sink_for(bad)).has_value());
  nlohmann::json line;
  ASSERT_TRUE(bad->next(line, 0));
  EXPECT_EQ(line["error"]["code"], "unknown_command");
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(submit_line(h, R"({"cmd":"estop"})", nullptr), Command::Estop);
  EXPECT_EQ(calls, 2);
}

TEST(ClientTest, ConnectErrorNamesThePath) {
  control::Client c;
  std::string error;
  EXPECT_LT(c.connect("/tmp/rbx1-no-such-daemon.sock", error), 0);
  EXPECT_NE(error.find("/tmp/rbx1-no-such-daemon.sock"), std::string::npos);
}

TEST(Server, ThePathAppearsOnlyOnceItAcceptsConnections) {
  // A client polling for the socket file (as scripts and the tests do while rbx1d starts) connects the instant
  // the file exists; it must never be refused. Repeated, because the window it guards against is microseconds.
  std::string path = "/tmp/rbx1-server-test-appear-" + std::to_string(getpid()) + ".sock";
  int refused = 0;
  for (int i = 0; i < 300; ++i) {
    ::unlink(path.c_str());
    Server server;
    std::atomic<bool> opened{false};
    std::thread opener([&] {
      std::string error;
      EXPECT_EQ(server.open(path, 0660, error), 0) << error;
      opened = true;
    });
    struct stat st {};
    while (::lstat(path.c_str(), &st) != 0 && !opened) {
    }
    int fd = connect_raw(path);
    if (fd < 0) ++refused;
    else ::close(fd);
    opener.join();
  }
  EXPECT_EQ(refused, 0) << "connections refused on a socket file that had just appeared";
  ::unlink(path.c_str());
}
