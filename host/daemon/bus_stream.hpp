// bus_stream.hpp - the socket's subscribe request: a bus subscription streamed to one client as event lines until
// it goes away. A client that reads slowly or never loses lines (each line says how many so far), never a job's
// time or the e-stop's.
#pragma once
#include <atomic>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "bus.hpp"
#include "reply.hpp"

namespace rbx1::daemon {

class BusStreams {
 public:
  static constexpr size_t kMaxStreams = 32;        // subscribers at once; one more is refused ("busy")
  static constexpr size_t kMaxBacklog = 16 * 1024;  // unsent bytes beyond which a stream's lines are dropped
  static constexpr int kStatusEveryMs = 2000;       // a status line at least this often (also on every change)

  explicit BusStreams(Bus& bus) : bus_(bus) {}
  ~BusStreams() { stop(); }
  // Streams the topics (a Topic mask) to reply until its client goes away or stop(); errors on reply when full.
  void start(unsigned topics, std::shared_ptr<Reply> reply);
  void stop();  // ends every stream (their replies get a final line)

 private:
  struct Stream {
    std::thread thread;
    std::shared_ptr<Subscription> sub;
    std::atomic<bool> done{false};
  };
  void pump(Stream& s, unsigned topics, const std::shared_ptr<Reply>& reply);
  Bus& bus_;
  std::mutex mu_;
  std::vector<std::unique_ptr<Stream>> streams_;
  bool stopped_ = false;
};

}  // namespace rbx1::daemon
