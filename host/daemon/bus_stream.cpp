// bus_stream.cpp - one thread per subscriber moves bus messages to its reply as event lines, holding none back
// from a client that does not read (they are dropped and counted instead).
#include "bus_stream.hpp"

#include <chrono>

#include <spdlog/spdlog.h>

namespace rbx1::daemon {

void BusStreams::start(unsigned topics, std::shared_ptr<Reply> reply) {
  std::lock_guard lock(mu_);
  std::erase_if(streams_, [](const auto& s) {
    if (!s->done) return false;
    s->thread.join();
    return true;
  });
  if (stopped_) return reply->error(ErrorCode::ShuttingDown, "rbx1d is shutting down");
  if (streams_.size() >= kMaxStreams)
    return reply->error(ErrorCode::Busy, "too many subscribers (" + std::to_string(kMaxStreams) + ")");
  auto s = std::make_unique<Stream>();
  s->sub = bus_.subscribe(topics);
  Stream& ref = *s;
  s->thread = std::thread([this, &ref, topics, reply] { pump(ref, topics, reply); });
  streams_.push_back(std::move(s));
}

void BusStreams::pump(Stream& s, unsigned topics, const std::shared_ptr<Reply>& reply) {
  uint64_t dropped = 0;  // lines this client's backlog could not take
  auto send = [&](const nlohmann::json& body) {
    if (reply->backlog() > kMaxBacklog) {
      ++dropped;
      return;
    }
    nlohmann::json line = body;
    line["missed"] = s.sub->missed() + dropped;
    reply->forward(line);
  };
  nlohmann::json names = nlohmann::json::array();
  for (Topic t : {Topic::Status, Topic::Events, Topic::Scans, Topic::Picks})
    if (topics & unsigned(t)) names.push_back(topic_name(t));
  reply->event("subscribed", {{"topics", names}});
  if (topics & unsigned(Topic::Status))
    if (auto st = bus_.last_status(); !st.is_null()) send(st);
  BusMessage m;
  while (!s.sub->closed() && !reply->client_gone()) {
    if (s.sub->next(m, 250)) send(*m.body);
  }
  s.sub->close();
  reply->result({{"unsubscribed", true}, {"missed", s.sub->missed() + dropped}});
  spdlog::debug("bus: a subscriber left after missing {} lines", s.sub->missed() + dropped);
  s.done = true;
}

void BusStreams::stop() {
  std::vector<std::unique_ptr<Stream>> all;
  {
    std::lock_guard lock(mu_);
    stopped_ = true;
    all.swap(streams_);
  }
  for (auto& s : all) s->sub->close();
  for (auto& s : all) s->thread.join();
}

}  // namespace rbx1::daemon
