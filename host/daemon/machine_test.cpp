// machine_test.cpp - the job runner against a scripted firmware (host/link's FakePeer) whose line dies at a chosen
// point: a failed STATUS never leaves an all-zero firmware status behind (issue 8, defect 5).
#include <thread>

#include <filesystem>

#include <gtest/gtest.h>

#include "daemon_setup.hpp"
#include "fake_peer.hpp"
#include "machine.hpp"
#include "reply.hpp"

using namespace rbx1;
using namespace rbx1::daemon;

namespace {


class MachineOnFakePeer : public ::testing::Test {
 protected:
  // The board's MAX_SPEED and ACCEL as CONFIG_GET answers them: the config's keys (data/rbx1.toml: the firmware
  // defaults), unless a test lowers one.
  virtual void board_limits(link::test::FakePeer& peer) {
    for (uint8_t j = 0; j < 6; ++j) {
      peer.set_config(j, RBX1_KEY_MAX_SPEED, 4000);
      peer.set_config(j, RBX1_KEY_ACCEL, 8000);
    }
  }
  virtual bool wait_ready() const { return true; }

  void SetUp() override {
    // On a machine shared with other test runs, a fresh pty's name may be one a stale symlink elsewhere still
    // points at, and another process may hold it ("in use by another program"): take another pty then.
    for (int attempt = 0; attempt < 3; ++attempt) {
      peer_ = std::make_unique<link::test::FakePeer>();
      board_limits(*peer_);
      config::Errors errors;
      Overrides o;
      o.port = peer_->slave_path();
      o.state_dir = (std::filesystem::temp_directory_path() / ("rbx1_machine_test_" + std::to_string(::getpid()))).string();
      ASSERT_TRUE(load_config(RBX1_DATA_DIR "/rbx1.toml", o, config_, errors)) << errors.joined();
      config_.link.timeout_ms = 100;  // a dead line is declared down in 0.3 s, not 0.6 s
      config_.link.retries = 2;
      config_.link.boot_wait_ms = 0;
      config_.daemon.reconnect_timeout_s = 0.3;
      machine_ = std::make_unique<Machine>(config_);
      std::string error;
      ASSERT_EQ(machine_->start(error), 0) << error;
      if (!wait_ready()) return;
      for (int i = 0; i < 100; ++i) {
        auto st = machine_->call(Command::Status);
        if (st.is_object() && st["result"].value("ready", false)) return;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
      machine_->stop();
      machine_.reset();
    }
    FAIL() << "never ready on the fake firmware";
  }
  void TearDown() override {
    if (peer_) peer_->silence_after_type = -1;
    if (machine_) machine_->stop();
  }
  // The firmware part of the status reply: what `rbx1 status` shows.
  nlohmann::json firmware() { return machine_->call(Command::Status)["result"]["firmware"]; }

  std::unique_ptr<link::test::FakePeer> peer_;
  Config config_;
  std::unique_ptr<Machine> machine_;
};

// A declared (homed, enabled) firmware's STATUS: an all-zero one would show homed 0, drivers off, queue_free 0.
void expect_real_status(const nlohmann::json& fw) {
  ASSERT_TRUE(fw.is_object()) << fw.dump();
  EXPECT_EQ(fw["homed"], 63) << fw.dump();
  EXPECT_EQ(fw["enabled"], true) << fw.dump();
  EXPECT_EQ(fw["queue_free"], 8) << fw.dump();
}

TEST_F(MachineOnFakePeer, HomeKeepsTheLastGoodStatusWhenTheLineDiesAfterTheMove) {
  expect_real_status(firmware());
  // The home move, the STATUS that shows it complete, then nothing: a STATUS after that fails.
  peer_->silence_after_count = 1;
  peer_->silence_after_type = RBX1_MSG_MOVE;
  auto r = machine_->call(Command::Home);
  ASSERT_TRUE(r.contains("result")) << r.dump();
  EXPECT_EQ(peer_->executed(RBX1_MSG_MOVE), 1);
  expect_real_status(firmware());
}

TEST_F(MachineOnFakePeer, ClearFaultKeepsTheLastGoodStatusWhenTheLineDiesAfterPreparing) {
  // CLEAR_FAULT, then the preparation's first STATUS, its 12 CONFIG_GETs of the board's limits and its final
  // STATUS; any STATUS after them fails.
  peer_->silence_after_count = 14;
  peer_->silence_after_type = RBX1_MSG_CLEAR_FAULT;
  auto r = machine_->call(Command::ClearFault);
  ASSERT_TRUE(r.contains("result")) << r.dump();
  expect_real_status(r["result"]["firmware"]);
  expect_real_status(firmware());
}

// The line dies in the preparation after CLEAR_FAULT (its first STATUS answered, the first CONFIG_GET not): the job
// and the status name what happened in words and what to do, never a bare errno ("failed (-110)").
TEST_F(MachineOnFakePeer, ALinkThatDiesSaysSoInWords) {
  peer_->silence_after_count = 1;
  peer_->silence_after_type = RBX1_MSG_CLEAR_FAULT;
  auto r = machine_->call(Command::ClearFault);
  ASSERT_TRUE(r.contains("error")) << r.dump();
  EXPECT_EQ(r["error"]["code"], "not_ready") << r.dump();
  const std::string why = peer_->slave_path() + ": CONFIG_GET MAX_SPEED of joint 1 failed: no answer from the "
                          "firmware after every retransmission (check the cable and the board's power)";
  EXPECT_EQ(r["error"]["message"], why);
  auto st = machine_->call(Command::Status)["result"];
  EXPECT_EQ(st["ready"], false) << st.dump();
  const std::string shown = st["link"].value("error", "");  // this, or the worker's next try: "STATUS failed: ..."
  EXPECT_NE(shown.find(" failed: no answer from the firmware"), std::string::npos) << st.dump();
  EXPECT_EQ(shown.find("(-"), std::string::npos) << st.dump();
}

// The board's ACCEL of joint 3 and MAX_SPEED of joint 5 below the config's keys: the daemon plans nothing (status
// not ready, naming both keys; a job not_ready with the reason) and never enables or homes the arm.
class MachineOnASlowerBoard : public MachineOnFakePeer {
 protected:
  void board_limits(link::test::FakePeer& peer) override {
    MachineOnFakePeer::board_limits(peer);
    peer.set_config(2, RBX1_KEY_ACCEL, 6000);
    peer.set_config(4, RBX1_KEY_MAX_SPEED, 3999);
  }
  bool wait_ready() const override { return false; }
};

TEST_F(MachineOnASlowerBoard, RefusesToPlanAndSaysWhy) {
  const std::string why =
      "the config's joint limits exceed the board's: arm.joints.j3.accel_steps_s2 = 8000 is above the board's ACCEL "
      "6000; arm.joints.j5.max_speed_steps_s = 4000 is above the board's MAX_SPEED 3999 (lower the keys, or raise "
      "the board's with CONFIG_SET: PROTOCOL.md)";
  nlohmann::json st;
  for (int i = 0; i < 500; ++i) {  // the worker's first preparation: up to 10 s on a loaded machine
    st = machine_->call(Command::Status)["result"];
    if (st["link"].value("error", "") == why) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(st["link"].value("error", ""), why) << st.dump();
  EXPECT_EQ(st["ready"], false) << st.dump();
  auto r = machine_->call(Command::Home);
  ASSERT_TRUE(r.contains("error")) << r.dump();
  EXPECT_EQ(r["error"]["code"], "not_ready") << r.dump();
  EXPECT_EQ(r["error"]["message"], why) << r.dump();
  EXPECT_EQ(peer_->executed(RBX1_MSG_ENABLE), 0);
  EXPECT_EQ(peer_->executed(RBX1_MSG_MOVE), 0);
}

}  // namespace
