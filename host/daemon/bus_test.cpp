// bus_test.cpp - the bus: topics reach only their subscribers, a full queue drops its oldest and counts it, a
// subscriber that never reads never blocks publish; the socket's stream holds back nothing from a slow client.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "bus.hpp"
#include "bus_stream.hpp"

using namespace rbx1::daemon;

TEST(Bus, TopicsReachOnlyTheirSubscribers) {
  Bus bus;
  auto status = bus.subscribe(unsigned(Topic::Status));
  auto both = bus.subscribe(unsigned(Topic::Status) | unsigned(Topic::Events));
  bus.publish(Topic::Events, {{"event", "step"}});
  bus.publish(Topic::Status, {{"ready", true}});
  BusMessage m;
  ASSERT_TRUE(status->next(m, 0));
  EXPECT_EQ((*m.body)["topic"], "status");
  EXPECT_EQ((*m.body)["seq"], 2);
  EXPECT_FALSE(status->next(m, 0));
  ASSERT_TRUE(both->next(m, 0));
  EXPECT_EQ((*m.body)["event"], "step");
  ASSERT_TRUE(both->next(m, 0));
  EXPECT_EQ((*m.body)["ready"], true);
  EXPECT_EQ(bus.last_status()["ready"], true);
}

TEST(Bus, AFullQueueDropsItsOldestAndCountsThem) {
  Bus bus;
  auto s = bus.subscribe(unsigned(Topic::Events), 3);
  for (int i = 0; i < 10; ++i) bus.publish(Topic::Events, {{"n", i}});
  EXPECT_EQ(s->missed(), 7u);
  BusMessage m;
  for (int want : {7, 8, 9}) {
    ASSERT_TRUE(s->next(m, 0));
    EXPECT_EQ((*m.body)["n"], want);
  }
  EXPECT_FALSE(s->next(m, 0));
}

TEST(Bus, SubscribersThatNeverReadCostPublishNothingMuch) {
  Bus bus;
  std::vector<std::shared_ptr<Subscription>> idle;
  for (int i = 0; i < 10; ++i) idle.push_back(bus.subscribe(unsigned(Topic::Events), 16));
  auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 10000; ++i) bus.publish(Topic::Events, {{"n", i}});
  double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (auto& sub : idle) EXPECT_EQ(sub->missed(), 10000u - 16u);
  EXPECT_LT(s, 20.0);  // only that it returns: 10 queues that are never read do not stop the publisher
}

TEST(Bus, ClosedOrDroppedSubscribersAreForgotten) {
  Bus bus;
  auto a = bus.subscribe(unsigned(Topic::Scans));
  { auto b = bus.subscribe(unsigned(Topic::Scans)); }
  a->close();
  bus.publish(Topic::Scans, {{"x", 1}});
  EXPECT_EQ(bus.subscribers(), 0u);
  BusMessage m;
  EXPECT_FALSE(a->next(m, 0));
}

namespace {
// A reply that collects its lines; backlog() as the test sets it.
struct Collector {
  std::mutex mu;
  std::vector<nlohmann::json> lines;
  std::atomic<size_t> backlog{0};
  std::atomic<bool> present{true};
  std::shared_ptr<Reply> reply(Command c) {
    return std::make_shared<Reply>(
        [this](const std::string& line, bool) {
          std::lock_guard lock(mu);
          lines.push_back(nlohmann::json::parse(line));
        },
        c, [this] { return present.load(); }, [this] { return backlog.load(); });
  }
  size_t count() {
    std::lock_guard lock(mu);
    return lines.size();
  }
  bool wait_for(size_t n) {
    for (int i = 0; i < 500 && count() < n; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    return count() >= n;
  }
};
}  // namespace

TEST(BusStreams, StreamsTheTopicsAskedForWithTheLastStatusFirst) {
  Bus bus;
  bus.publish(Topic::Status, {{"ready", false}});
  Collector c;  // outlives the streams, which write to it until they stop
  BusStreams streams(bus);
  streams.start(unsigned(Topic::Status) | unsigned(Topic::Events), c.reply(Command::Subscribe));
  ASSERT_TRUE(c.wait_for(2));  // subscribed, the last status
  bus.publish(Topic::Scans, {{"detections", nlohmann::json::object()}});
  bus.publish(Topic::Events, {{"event", "step"}, {"req", 4}});
  ASSERT_TRUE(c.wait_for(3));
  c.present = false;  // the client went away: its stream ends with a final line
  ASSERT_TRUE(c.wait_for(4));
  std::lock_guard lock(c.mu);
  EXPECT_EQ(c.lines[0]["event"], "subscribed");
  EXPECT_EQ(c.lines[0]["topics"], nlohmann::json({"status", "events"}));
  EXPECT_EQ(c.lines[1]["topic"], "status");
  EXPECT_EQ(c.lines[1]["ready"], false);
  EXPECT_EQ(c.lines[2]["topic"], "events");
  EXPECT_EQ(c.lines[2]["event"], "step");
  EXPECT_EQ(c.lines[2]["missed"], 0);
  EXPECT_EQ(c.lines[3]["result"]["unsubscribed"], true);
}

TEST(BusStreams, AClientThatDoesNotReadLosesLinesCounted) {
  Bus bus;
  Collector c;
  BusStreams streams(bus);
  streams.start(unsigned(Topic::Events), c.reply(Command::Subscribe));
  ASSERT_TRUE(c.wait_for(1));
  c.backlog = BusStreams::kMaxBacklog + 1;  // its socket holds that much unsent
  for (int i = 0; i < 5; ++i) bus.publish(Topic::Events, {{"event", "step"}, {"n", i}});
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(c.count(), 1u);
  c.backlog = 0;  // it reads again: the next line says how many it lost
  bus.publish(Topic::Events, {{"event", "step"}, {"n", 5}});
  ASSERT_TRUE(c.wait_for(2));
  {
    std::lock_guard lock(c.mu);
    EXPECT_EQ(c.lines[1]["n"], 5);
    EXPECT_EQ(c.lines[1]["missed"], 5);
  }
  streams.stop();
  ASSERT_TRUE(c.wait_for(3));
  std::lock_guard lock(c.mu);
  EXPECT_EQ(c.lines[2]["result"]["missed"], 5);
}

TEST(BusStreams, RefusesBeyondItsLimit) {
  Bus bus;
  std::vector<std::unique_ptr<Collector>> cs;
  BusStreams streams(bus);
  for (size_t i = 0; i <= BusStreams::kMaxStreams; ++i) {
    cs.push_back(std::make_unique<Collector>());
    streams.start(unsigned(Topic::Status), cs.back()->reply(Command::Subscribe));
  }
  ASSERT_TRUE(cs.back()->wait_for(1));
  {
    std::lock_guard lock(cs.back()->mu);
    EXPECT_EQ(cs.back()->lines[0]["error"]["code"], "busy");
  }
  streams.stop();
}

// A sort writes its history rows after a failure deep in its steps: its final line waits for them (FinalHeld).
TEST(Reply, AFinalLineHeldGoesOutWhenItsHolderEnds) {
  std::vector<std::pair<std::string, bool>> lines;
  Reply r([&](const std::string& line, bool final) { lines.emplace_back(line, final); }, Command::Sort);
  {
    Reply::FinalHeld held(r);
    r.event("scan");
    r.error(ErrorCode::PickUnverified, "blind twice");
    EXPECT_TRUE(r.finished());
    r.result(nlohmann::json::object());  // a second final line is still refused
    ASSERT_EQ(lines.size(), 1u);
    EXPECT_FALSE(lines[0].second);
  }
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_TRUE(lines[1].second);
  EXPECT_EQ(nlohmann::json::parse(lines[1].first)["error"]["code"], "pick_unverified");
}

// A job's outcome in the history is the code of the error that ended its reply (the sort's end_failed).
TEST(Reply, KeepsTheCodeOfTheErrorThatEndedIt) {
  Reply r([](const std::string&, bool) {}, Command::Sort);
  EXPECT_FALSE(r.error_code());
  r.error("estop", "the e-stop was pressed during the look");
  r.error(ErrorCode::PickUnverified, "too late: the reply has ended");
  EXPECT_EQ(r.error_code().value_or(""), "estop");
  Reply ok([](const std::string&, bool) {}, Command::Sort);
  ok.result({{"outcome", "done"}});
  ok.error(ErrorCode::Busy, "after the result");
  EXPECT_FALSE(ok.error_code());
}

TEST(Reply, WithoutAHolderTheFinalLineGoesOutAtOnce) {
  std::vector<std::string> lines;
  Reply r([&](const std::string& line, bool) { lines.push_back(line); }, Command::Sort);
  r.result({{"outcome", "done"}});
  ASSERT_EQ(lines.size(), 1u);
  { Reply::FinalHeld late(r); }  // held after the end: nothing is written twice
  EXPECT_EQ(lines.size(), 1u);
}
