// link.hpp - the host side of the RBX1 link: requests one at a time or streamed with a window in flight over a
// serial port, e-stop from any thread.
#pragma once
#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cerrno>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "config.hpp"
#include "rbx1_proto.h"
#include "window_sender.hpp"

namespace rbx1::link {

// The [link] table of the config file.
struct LinkConfig {
  std::string port;        // e.g. /dev/rbx1 (udev name), /dev/ttyACM0, or a simulator's pty
  int baud = 115200;       // 115200, 230400 or 250000
  int timeout_ms = 100;    // per transmission (PROTOCOL.md: 100 ms)
  int retries = 5;         // retransmissions before the link is declared down (PROTOCOL.md: 5)
  int heartbeat_ms = 250;  // idle interval between HEARTBEATs; must stay below the firmware's HEARTBEAT_MS
  int window = 8;          // requests in flight in stream() at most (also limited by the firmware's HELLO window)
  int boot_wait_ms = 8000; // how long open() waits for a board in its bootloader (the first open after plug-in or
                           // after flashing resets an Arduino): HELLO, 6 s of silence, HELLO again
};
void parse_link_config(rbx1::config::Section link, LinkConfig& out);

// Counters since construction (they survive reconnects).
struct LinkStats {
  uint64_t requests = 0;         // requests completed with a response
  uint64_t retransmissions = 0;  // frames sent again (timeout or NAK; a go-back counts each frame it resends)
  uint64_t timeouts = 0;         // transmissions that got no response in time
  uint64_t naks = 0;             // NAK frames received
  uint64_t stale = 0;            // responses that matched no outstanding request (late duplicates etc.)
  uint64_t rejected = 0;         // received frames with a bad CRC or length
  uint64_t link_down = 0;        // requests that failed after all retransmissions
  uint64_t reconnects = 0;       // successful reconnect() calls
  uint64_t bytes_sent = 0;
  uint64_t bytes_received = 0;
  uint64_t probes = 0;           // stream(): probes written (PROTOCOL.md "Probe")
};

// One request of a stream(): type and payload in; answered, and the response payload (status first), out.
struct StreamRequest {
  uint8_t type = 0;
  uint8_t len = 0;
  uint8_t payload[RBX1_MAX_PAYLOAD] = {};
  bool answered = false;
  uint8_t resp_len = 0;
  uint8_t resp[RBX1_MAX_PAYLOAD] = {};
};

// A negative errno of the calls below in words, with what to do ("no answer from the firmware after every
// retransmission (check the cable and the board's power)"); messages to users carry this, never the number.
std::string error_text(int r);
// "PORT: WHAT failed: " and error_text(r): a request that got no answer, for a user's message.
std::string failed(const std::string& port, const std::string& what, int r);

// One link to one firmware. Requests (request(), the typed helpers and stream()) are serialised, whichever thread
// calls: request() has one in flight, stream() up to window() (PROTOCOL.md "Window"). estop() bypasses that
// queue. A reader thread decodes every incoming byte and hands each answer to the waiting caller.
// All int-returning calls give 0 when a response arrived (its status is the typed struct's first field) or a
// negative errno: -ETIMEDOUT link down after all retransmissions, -ENODEV/-EIO port gone (reconnect() then),
// -ENOTCONN not open, -EPROTO protocol version mismatch, -EBADMSG response of the wrong length,
// -EOPNOTSUPP the firmware does not know the message type (NAK UNKNOWN_TYPE: resending cannot help).
class Link {
 public:
  Link();
  ~Link();
  Link(const Link&) = delete;
  Link& operator=(const Link&) = delete;

  // Opens the serial port and performs the HELLO handshake. error reads "PORT: reason".
  int open(const std::string& port, int baud, std::string& error);
  int open(const LinkConfig& config, std::string& error);
  // Uses an already open fd (a pipe end, a pty master, a socket): no termios changes. Takes ownership. HELLO.
  int open_fd(int fd, const std::string& name, std::string& error);
  void close();
  bool connected() const { return connected_.load(); }
  const std::string& name() const { return name_; }

  // After the device vanished (-ENODEV/-EIO): reopen the same path if it is back, HELLO, and continue
  // numbering from the firmware's last_seq + 1. -ENOENT while the path is absent.
  int reconnect(std::string& error);
  // Calls reconnect() every 50 ms until it succeeds or timeout_ms passes.
  int wait_reconnect(int timeout_ms, std::string& error);

  // Per-transmission timeout and retransmission count (defaults from PROTOCOL.md).
  void set_timing(int timeout_ms, int retries);
  // How long open()/reconnect() wait for an unanswered HELLO (a board in its bootloader). Default 8000.
  void set_boot_wait(int ms) { boot_wait_ms_ = ms; }

  // Any request by type with a raw payload; resp receives the response payload (status first).
  int request(uint8_t type, const uint8_t* payload, uint8_t len, uint8_t* resp, uint8_t& resp_len);

  // Sends reqs in order with up to window() in flight (PROTOCOL.md "Window": resends driven by the answers, NAKs and
  // probes; on a timeout of the oldest unanswered one, its deadline from the line model at the port's rate, every
  // unanswered one again). 0 when every one was answered; else a negative errno as request() gives it, with each
  // request's `answered` saying whether its response arrived (the firmware runs requests in SEQ order, so an
  // answered request means every one before it was handled, answered or not).
  int stream(std::vector<StreamRequest>& reqs);
  // MOVE requests as a stream; out[i] is valid where answered[i].
  int move_stream(const std::vector<rbx1_move_req>& reqs, std::vector<rbx1_move_resp>& out,
                  std::vector<bool>& answered);
  // Requests in flight in stream(): min(set_window(), the firmware's HELLO window); 1 before a HELLO.
  int window() const;
  void set_window(int max_in_flight);
  // stream() writes a new request only while fewer than `frames` copies are on the line beyond the latest one an
  // answer or NAK was about (PROTOCOL.md "Pacing"; default kAhead); 0 writes the whole window at once.
  void set_ahead(int frames);
  static constexpr int kAhead = 4;

  // Typed helpers, one per message.
  int hello(rbx1_hello_resp& out);
  int status(rbx1_status_resp& out);
  int heartbeat(rbx1_heartbeat_resp& out);
  int move(const rbx1_move_req& req, rbx1_move_resp& out);
  int gripper(const rbx1_gripper_req& req, rbx1_gripper_resp& out);
  int home(uint8_t joint_mask, rbx1_home_resp& out);
  int stop(rbx1_stop_resp& out);
  int clear_fault(rbx1_clear_fault_resp& out);
  int enable(bool on, rbx1_enable_resp& out);
  int set_position(const int32_t position[RBX1_JOINTS], rbx1_set_position_resp& out);
  int config_get(uint8_t joint, uint8_t key, rbx1_config_get_resp& out);
  int config_set(uint8_t joint, uint8_t key, int32_t value, rbx1_config_set_resp& out);
  int config_reset(rbx1_config_reset_resp& out);

  // E-stop: callable from any thread, also while another request waits. The frame goes on the wire at once
  // (its own write lock, its own SEQ); then waits for the acknowledgement, retransmitting like any request
  // (ESTOP is idempotent). out.status is the firmware's answer.
  int estop(rbx1_estop_resp& out);
  int estop();

  // Sends a HEARTBEAT if no request completed for heartbeat_ms; 0 when none was due.
  int heartbeat_if_due(int heartbeat_ms);
  // A background thread calling heartbeat_if_due(period_ms) until stop_heartbeat() or close().
  void start_heartbeat(int period_ms);
  void stop_heartbeat();

  rbx1_hello_resp firmware() const;  // the last successful HELLO response
  LinkStats stats() const;
  uint8_t next_seq() const;

 private:
  struct Waiter {  // a single request (or the e-stop) in flight awaiting its answer
    uint8_t seq = 0, type = 0;
    bool done = false, nak = false;
    uint8_t nak_reason = 0;
    uint8_t len = 0;
    uint8_t payload[RBX1_MAX_PAYLOAD];
  };

  int attach(int fd, std::string& error);  // starts the reader thread and performs HELLO
  int handshake(std::string& error);
  void detach();                             // stops the reader thread and closes the fd
  void reader_loop(int fd, int wake_fd);
  static void on_frame(void* ctx, const rbx1_frame* frame);
  static void on_reject(void* ctx, uint8_t status, uint8_t seq, uint8_t has_seq);
  void port_gone(int err);
  int down_error() const { return gone_error_ ? -gone_error_ : -ENOTCONN; }  // under state_mu_
  int write_frame(const uint8_t* frame, size_t n);
  int transact(Waiter& w, bool estop, const uint8_t* frame, size_t n, uint8_t* resp, uint8_t& resp_len);
  int request_locked(uint8_t type, const uint8_t* payload, uint8_t len, uint8_t* resp, uint8_t& resp_len);
  int resync_locked();
  int run_stream(WindowSender& sender, const std::vector<std::array<uint8_t, RBX1_MAX_FRAME>>& frames,
                 const std::vector<uint8_t>& sizes);
  int write_stream(const std::vector<SenderWrite>& writes, const std::vector<std::array<uint8_t, RBX1_MAX_FRAME>>& frames,
                   const std::vector<uint8_t>& sizes, std::unique_lock<std::mutex>& lock);
  void count_stream(const WindowSender& sender, SenderCounters& counted);  // under state_mu_
  template <typename Resp>
  int typed(uint8_t type, const uint8_t* payload, uint8_t len, Resp& out,
            uint8_t (*unpack)(Resp*, const uint8_t*, uint8_t));

  std::string path_, name_;
  int baud_ = 0;  // 0 when opened with open_fd (no termios, no reopen)
  std::atomic<int> timeout_ms_{100}, retries_{5}, boot_wait_ms_{2500}, max_window_{8}, ahead_{kAhead};

  std::mutex request_mu_;  // one request() or stream() at a time
  std::mutex estop_mu_;    // one e-stop exchange at a time
  std::mutex write_mu_;    // whole frames on the wire, never interleaved
  mutable std::mutex state_mu_;
  std::condition_variable state_cv_;
  int fd_ = -1, wake_fd_ = -1;
  std::thread reader_;
  std::atomic<bool> connected_{false};
  int gone_error_ = 0;     // the errno that took the port down (under state_mu_)
  uint8_t next_seq_ = 0;   // under state_mu_
  std::atomic<bool> resync_{false};  // a HELLO before the next request
  std::vector<Waiter*> waiting_;     // the single request in flight (under state_mu_)
  WindowSender* stream_ = nullptr;   // the stream in progress: told of every frame first (under state_mu_)
  Waiter* estop_waiting_ = nullptr;  // the outstanding e-stop (under state_mu_)
  rbx1_decoder decoder_;   // reader thread only
  std::vector<uint8_t> recent_;            // reader thread only: bytes received during the handshake
  std::atomic<bool> handshaking_{false};   // HELLO of handshake() in progress: the reader looks for version 3 frames
  std::atomic<bool> v3_seen_{false};       // a version 3 firmware's frame was received during the handshake
  rbx1_hello_resp hello_{};
  std::chrono::steady_clock::time_point last_done_;  // under state_mu_

  std::mutex hb_mu_;
  std::condition_variable hb_cv_;
  std::thread hb_thread_;
  bool hb_stop_ = false;

  struct Counters {
    std::atomic<uint64_t> requests{0}, retransmissions{0}, timeouts{0}, naks{0}, stale{0}, rejected{0},
        link_down{0}, reconnects{0}, bytes_sent{0}, bytes_received{0}, probes{0};
  } counters_;
};

}  // namespace rbx1::link
