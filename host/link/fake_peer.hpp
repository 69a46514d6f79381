// fake_peer.hpp - a scripted firmware on the master side of a pty pair, for the link tests.
#pragma once
#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "rbx1_proto.h"
#include "rbx1_window.h"

namespace rbx1::link::test {

// Speaks the protocol like the firmware (the window: in-order, at-most-once execution with remembered answers,
// requests ahead of a gap held; ESTOP exempt, it drops the held ones), with fault knobs the tests set before or between requests.
class FakePeer {
 public:
  struct Received {
    uint8_t seq, type;
    uint32_t crc;
    std::chrono::steady_clock::time_point at;
  };

  FakePeer();  // opens the pty pair and starts the peer thread
  ~FakePeer();
  const std::string& slave_path() const { return slave_; }
  void hang_up();  // closes the master: the slave side sees a hang-up, as when a USB device vanishes

  // Knobs.
  std::atomic<int> drop_next{0};       // ignore the next N frames of a request type (silence; probes pass)
  std::atomic<int> drop_seq{-1};       // ignore the next drop_seq_times frames of a request type with this SEQ
  std::atomic<int> drop_seq_times{0};
  std::atomic<int> drop_probes{0};     // ignore the next N frames of no request type (the link's probes)
  std::atomic<int> nak_next{0};        // answer the next N frames with a NAK, unexecuted ...
  std::atomic<uint8_t> nak_reason{RBX1_BAD_CRC};  // ... of this reason
  std::atomic<int> corrupt_next{0};    // execute, but send the next N responses with a broken CRC
  std::atomic<bool> duplicate{false};  // send every response twice
  std::atomic<bool> stale_first{false};  // before each response, send one with another SEQ
  std::atomic<int> delay_type{-1};     // hold responses of this type ...
  std::atomic<int> delay_ms{0};        // ... for this long (the peer keeps reading meanwhile)
  std::atomic<int> delay_all_ms{0};    // every answer and NAK this late, in order (a slow firmware)
  std::atomic<uint8_t> proto_version{RBX1_PROTO_VERSION};
  std::atomic<bool> v4_frames{false};  // send frames as protocol version 4 did: no parity bytes after the CRC
  std::atomic<uint8_t> last_seq{41};   // reported by HELLO until a request is executed
  std::atomic<uint8_t> window_size{RBX1_WINDOW};  // HELLO's window
  // After the next executed request of this type, execute silence_after_count more new requests (retransmissions
  // meanwhile answered as usual), then answer nothing at all (a line that dies at a chosen point of an exchange);
  // -1 disarms and ends the silence.
  std::atomic<int> silence_after_type{-1};
  std::atomic<int> silence_after_count{0};

  // CONFIG_GET answers this value for (joint, key); any other is joint * 100 + key.
  void set_config(uint8_t joint, uint8_t key, int32_t value) {
    std::lock_guard<std::mutex> lock(mu_);
    config_[joint << 8 | key] = value;
  }

  // Records.
  std::vector<Received> received() const;
  int executed(uint8_t type) const;
  int cached_replies() const { return cached_replies_; }
  int refused() const { return refused_; }  // NAKs SEQ_GAP and SEQ_OLD sent
  int held() const { return held_; }        // NAKs HELD sent (requests kept ahead of a gap, copies included)
  int unknown() const { return unknown_; }  // NAKs UNKNOWN_TYPE sent (frames of no request type: the link's probes)
  std::vector<int32_t> move_targets() const {  // MOVE target[0] in the order executed
    std::lock_guard<std::mutex> lock(mu_);
    return move_targets_;
  }
  std::chrono::steady_clock::time_point sent_at(uint8_t type) const;  // last response of this type sent

 private:
  struct Pending {
    std::chrono::steady_clock::time_point due;
    std::vector<uint8_t> bytes;
    uint8_t type;
  };
  void loop();
  static void on_frame(void* ctx, const rbx1_frame* f);
  void handle(const rbx1_frame& f);
  uint8_t execute(const rbx1_frame& f, uint8_t* resp);
  void respond(uint8_t seq, uint8_t type, const uint8_t* payload, uint8_t len, bool corrupt);
  void send(const std::vector<uint8_t>& bytes, uint8_t type);

  int master_ = -1;
  std::string slave_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  rbx1_decoder decoder_;
  mutable std::mutex mu_;
  std::map<int, int32_t> config_;  // set_config (under mu_)
  std::vector<Received> received_;
  std::map<uint8_t, int> executed_;
  std::vector<int32_t> move_targets_;
  std::map<uint8_t, std::chrono::steady_clock::time_point> sent_at_;
  std::vector<Pending> pending_;
  std::atomic<int> cached_replies_{0};
  std::atomic<int> refused_{0};
  std::atomic<int> held_{0};
  std::atomic<int> unknown_{0};
  rbx1_window window_{};  // at-most-once memory, as in the firmware
  uint16_t moves_done_ = 0;
  uint8_t homed_ = 0, enabled_ = 0;  // SET_POSITION/HOME and ENABLE, reported by STATUS
  int silence_left_ = -1;            // frames still answered before the silence; -1 none armed
};

}  // namespace rbx1::link::test
