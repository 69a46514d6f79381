// motion_journal.cpp - the at-most-once bookkeeping of a job's queue entries: answers, counters, outages, flushes.
#include "motion_journal.hpp"

#include "error_codes.hpp"

#include <algorithm>

#include <spdlog/spdlog.h>

namespace rbx1::daemon {

namespace {
size_t since(uint16_t now, uint16_t then) { return size_t(uint16_t(now - then)); }

bool refusal(uint8_t status) {  // room or state comes back, or a fault latched since the last STATUS
  return status == RBX1_QUEUE_FULL || status == RBX1_BUSY || status == RBX1_FAULT_ACTIVE;
}

bool answered_ok(const link::StreamRequest& r) { return r.answered && r.resp_len >= 1 && r.resp[0] == RBX1_OK; }
}  // namespace

MotionJournal::MotionJournal(std::vector<std::string> names, const rbx1_status_resp& base)
    : names_(std::move(names)), base_(base), queue_free_(base.queue_free) {}

size_t MotionJournal::next_batch() const { return std::min<size_t>(queue_free_, names_.size() - sent_); }

size_t MotionJournal::since_base_accepted(const rbx1_status_resp& st) const {
  return since(st.moves_accepted, base_.moves_accepted);
}

void MotionJournal::accept(std::vector<JournalEvent>& events) {
  events.push_back({JournalEvent::Sent, sent_});
  ++accepted_;
  ++sent_;
}

BatchEnd MotionJournal::take_answers(const std::vector<link::StreamRequest>& batch, std::vector<JournalEvent>& events,
                                     JournalError& error) {
  batch_ = batch;
  batch_first_ = sent_;
  const size_t count = batch.size();
  size_t k = 0;  // answers taken in order
  for (; k < count && batch[k].answered; ++k) {
    uint8_t status = batch[k].resp_len >= 1 ? batch[k].resp[0] : uint8_t(RBX1_BAD_LENGTH);
    if (batch[k].resp_len >= 2) queue_free_ = batch[k].resp[1];
    if (refusal(status)) {
      // Poll and retry; a fault is for the job's fault checks (e-stop ends it, a lost heartbeat is recovered).
      queue_free_ = 0;
      for (size_t j = k + 1; j < count; ++j)
        if (answered_ok(batch[j])) {
          error = {code_name(ErrorCode::Rejected), "firmware accepted step " + std::to_string(batch_first_ + j + 1) +
                                   " after refusing step " + std::to_string(batch_first_ + k + 1) +
                                   "; the queue's order is lost"};
          return BatchEnd::Refused;
        }
      return BatchEnd::Refused;
    }
    if (status != RBX1_OK) {
      error = {code_name(ErrorCode::Rejected), "firmware refused step " + std::to_string(sent_ + 1) + " (" + names_[sent_] +
                               "): " + rbx1_status_name(status)};
      return BatchEnd::Refused;
    }
    accept(events);
  }
  return k == count ? BatchEnd::Accepted : BatchEnd::Cut;
}

JournalError MotionJournal::outage(const rbx1_status_resp& st, std::vector<JournalEvent>& events) {
  const size_t count = batch_.size(), k = sent_ - batch_first_;
  const size_t queued = since_base_accepted(st);
  const size_t ran = queued >= accepted_ ? queued - accepted_ : count + 1;  // unanswered entries it queued
  bool fits = ran <= count - k;
  for (size_t j = k; fits && j < count; ++j)  // an answer must agree: OK exactly for the first `ran`
    if (batch_[j].answered && batch_[j].resp_len >= 1 && (batch_[j].resp[0] == RBX1_OK) != (j < k + ran))
      fits = false;
  if (!fits)
    return {code_name(ErrorCode::FirmwareReset), "the firmware's counters (accepted " + std::to_string(queued) +
                                  " since the job began) disagree with the " + std::to_string(accepted_) +
                                  " entries this job knows plus " + std::to_string(count - k) +
                                  " unanswered; refusing to guess the arm's state"};
  for (size_t j = k; j < count && j <= k + ran; ++j) {  // the accepted ones, and the first one not accepted
    const size_t step = batch_first_ + j;
    const bool took = j < k + ran;
    spdlog::info("motion: step {} ({}) {} before the link went down", step + 1, names_[step],
                 took ? "was accepted" : "was not accepted");
    events.push_back({JournalEvent::Outage, step, took});
    if (!took) break;
    accept(events);
  }
  return reconcile(st, events);
}

JournalError MotionJournal::reconcile(const rbx1_status_resp& st, std::vector<JournalEvent>& events) {
  const size_t n = names_.size();
  const size_t a = since_base_accepted(st), d = since(st.moves_done, base_.moves_done),
               f = since(st.moves_flushed, base_.moves_flushed);
  if (a != accepted_ || d + f > a || d > n)
    return {code_name(ErrorCode::FirmwareReset), "the firmware's counters (accepted " + std::to_string(a) + ", done " +
                                  std::to_string(d) + ", flushed " + std::to_string(f) +
                                  " since the job began) disagree with the " + std::to_string(accepted_) +
                                  " entries this job sent; refusing to guess the arm's state"};
  while (done_ < d) {
    events.push_back({JournalEvent::StepDone, done_});
    ++done_;
    announce(events);
  }
  const size_t queued = a - d - f;
  if (done_ + queued < sent_) {  // flushed: those entries never ran; the job's fault checks decide what follows
    flushed_ += sent_ - done_ - queued;
    sent_ = done_ + queued;
    announced_ = std::min(announced_, sent_);
  }
  queue_free_ = st.queue_free;
  return {};
}

void MotionJournal::announce(std::vector<JournalEvent>& events) {
  if (announced_ < sent_ && announced_ == done_) {
    events.push_back({JournalEvent::Step, announced_});
    ++announced_;
  }
}

size_t MotionJournal::resend_flushed() {
  size_t n = flushed_;
  flushed_ = 0;
  return n;
}

}  // namespace rbx1::daemon
