// link_partial_frame_test.cpp - the host drops a partial frame after 50 ms of silence (PROTOCOL.md, inter-byte
// timeout): a response that follows a line glitch is taken at once, not after a retransmission.
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <thread>

#include <gtest/gtest.h>

#include "link.hpp"
#include "rbx1_proto.h"

namespace {

// A firmware stand-in on one end of a socketpair: answers HELLO and STATUS; before each STATUS response it sends
// the first bytes of a frame that never ends (SYNC, the longest LEN, SEQ, TYPE, three payload bytes) and then
// stays silent for gap_ms.
class GlitchPeer {
 public:
  GlitchPeer(int fd, int gap_ms) : fd_(fd), gap_ms_(gap_ms) {
    rbx1_decoder_init(&decoder_, &GlitchPeer::on_frame, nullptr, this);
    thread_ = std::thread([this] { loop(); });
  }
  ~GlitchPeer() {
    stop_ = true;
    ::shutdown(fd_, SHUT_RDWR);
    thread_.join();
    ::close(fd_);
  }
  int statuses() const { return statuses_; }

 private:
  static void on_frame(void* ctx, const rbx1_frame* f) { static_cast<GlitchPeer*>(ctx)->handle(*f); }
  void send(uint8_t seq, uint8_t type, const uint8_t* payload, uint8_t len) {
    uint8_t frame[RBX1_MAX_FRAME];
    size_t n = rbx1_frame_encode(frame, sizeof frame, seq, type, payload, len);
    if (::write(fd_, frame, n) != ssize_t(n)) stop_ = true;
  }
  void handle(const rbx1_frame& f) {
    uint8_t resp[RBX1_MAX_PAYLOAD];
    if (f.type == RBX1_MSG_HELLO) {
      rbx1_hello_resp h{};
      h.status = RBX1_OK;
      h.proto_version = RBX1_PROTO_VERSION;
      h.joints = 6;
      h.queue_size = 8;
      h.last_seq = uint8_t(f.seq - 1);
      send(f.seq, RBX1_RESPONSE(f.type), resp, rbx1_hello_resp_pack(&h, resp));
    } else if (f.type == RBX1_MSG_STATUS) {
      ++statuses_;
      const uint8_t partial[] = {RBX1_SYNC, RBX1_MAX_PAYLOAD, f.seq, RBX1_RESPONSE(RBX1_MSG_STATUS), 1, 2, 3};
      if (::write(fd_, partial, sizeof partial) != ssize_t(sizeof partial)) stop_ = true;
      std::this_thread::sleep_for(std::chrono::milliseconds(gap_ms_));
      rbx1_status_resp s{};
      s.queue_free = 8;
      s.position[0] = 4242;
      send(f.seq, RBX1_RESPONSE(f.type), resp, rbx1_status_resp_pack(&s, resp));
    } else {
      resp[0] = RBX1_OK;
      send(f.seq, RBX1_RESPONSE(f.type), resp, 1);
    }
  }
  void loop() {
    uint8_t buf[256];
    while (!stop_) {
      ssize_t n = ::read(fd_, buf, sizeof buf);
      if (n <= 0) return;
      rbx1_decoder_feed(&decoder_, buf, size_t(n));
    }
  }
  int fd_;
  int gap_ms_;
  rbx1_decoder decoder_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<int> statuses_{0};
};

}  // namespace

// 80 ms of silence after the fragment (more than the 50 ms inter-byte timeout): the link has dropped the fragment
// when the real response starts, so the first transmission is answered. A link that kept the fragment would
// swallow the response into its 68-byte candidate frame, wait for bytes that never come, and retransmit after its
// 1 s timeout.
TEST(LinkPartialFrame, AFragmentIsDroppedAfterTheInterByteTimeout) {
  int sv[2];
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv), 0);
  GlitchPeer peer(sv[1], 80);
  rbx1::link::Link link;
  link.set_timing(1000, 3);
  std::string error;
  ASSERT_EQ(link.open_fd(sv[0], "glitch", error), 0) << error;
  auto before = link.stats();
  for (int i = 0; i < 3; ++i) {
    rbx1_status_resp st{};
    ASSERT_EQ(link.status(st), 0) << "STATUS " << i;
    EXPECT_EQ(st.position[0], 4242);
  }
  auto after = link.stats();
  EXPECT_EQ(after.retransmissions - before.retransmissions, 0u) << "a fragment held the response back";
  EXPECT_EQ(peer.statuses(), 3);
  link.close();
}
