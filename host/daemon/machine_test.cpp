// machine_test.cpp - the job runner against a scripted firmware (host/link's FakePeer) whose line dies at a chosen
// point: a failed STATUS never leaves an all-zero firmware status behind (issue 8, defect 5).
#include <thread>

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
  void SetUp() override {
    // On a machine shared with other test runs, a fresh pty's name may be one a stale symlink elsewhere still
    // points at, and another process may hold it ("in use by another program"): take another pty then.
    for (int attempt = 0; attempt < 3; ++attempt) {
      peer_ = std::make_unique<link::test::FakePeer>();
      config::Errors errors;
      Overrides o;
      o.port = peer_->slave_path();
      ASSERT_TRUE(load_config(RBX1_DATA_DIR "/rbx1.toml", o, config_, errors)) << errors.joined();
      config_.link.timeout_ms = 100;  // a dead line is declared down in 0.3 s, not 0.6 s
      config_.link.retries = 2;
      config_.link.boot_wait_ms = 0;
      config_.daemon.reconnect_timeout_s = 0.3;
      machine_ = std::make_unique<Machine>(config_);
      std::string error;
      ASSERT_EQ(machine_->start(error), 0) << error;
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
  // CLEAR_FAULT, then the two STATUS of the preparation (first and final); any STATUS after them fails.
  peer_->silence_after_count = 2;
  peer_->silence_after_type = RBX1_MSG_CLEAR_FAULT;
  auto r = machine_->call(Command::ClearFault);
  ASSERT_TRUE(r.contains("result")) << r.dump();
  expect_real_status(r["result"]["firmware"]);
  expect_real_status(firmware());
}

}  // namespace
