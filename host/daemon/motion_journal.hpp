// motion_journal.hpp - which of a job's queue entries the firmware accepted, completed or flushed, from the answers
// to what was sent and the firmware's counters, across outages: the at-most-once bookkeeping, without I/O.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "link.hpp"

namespace rbx1::daemon {

// One thing the journal learned, in the order the job reports it (each becomes an event of the job).
struct JournalEvent {
  enum Kind {
    Sent,      // the firmware accepted entry `step`
    StepDone,  // entry `step` completed
    Step,      // entry `step` is now at the head of the queue (its motion started)
    Outage,    // an unanswered entry of a batch cut by an outage, resolved from the counters: `accepted` or not
  };
  Kind kind;
  size_t step;
  bool accepted = false;  // Outage only
};

// An error of the journal: code ("firmware_reset", "rejected") and message, both empty when none.
struct JournalError {
  std::string code, message;
  explicit operator bool() const { return !code.empty(); }
};

// What the answers to a batch left: every entry accepted, a refusal (room or state comes back: poll first), or
// entries unanswered (the link failed under the batch: outage() once the firmware can be asked).
enum class BatchEnd { Accepted, Refused, Cut };

// The journal, from the firmware's own counters: of the entries accepted since the job began (A), D completed
// and F were flushed; the rest (A - D - F) wait in its queue. Entries complete in order, so entries [0, D) are
// done and [D, D + queued) are queued; a flush (STOP, heartbeat loss) moves sent() back so that the rest is sent
// again (moves are absolute targets: resending one that never ran is safe).
class MotionJournal {
 public:
  // names: the job's entries (for messages); base: the STATUS at the job's start (the counters it counts from).
  MotionJournal(std::vector<std::string> names, const rbx1_status_resp& base);

  size_t size() const { return names_.size(); }
  size_t sent() const { return sent_; }        // the next entry to send
  size_t done() const { return done_; }        // entries completed
  size_t accepted() const { return accepted_; }
  size_t flushed() const { return flushed_; }  // entries flushed and not yet sent again
  bool finished() const { return done_ == names_.size(); }
  uint8_t queue_free() const { return queue_free_; }
  // Entries the next batch holds: at most the queue's room, so none is refused QUEUE_FULL between accepted ones
  // and the firmware (running requests in SEQ order) accepts a prefix of any batch whose answers were lost.
  size_t next_batch() const;

  // The answers to the batch of entries sent()..sent() + batch.size() - 1 (link::Link::stream's requests, in
  // order). Accepted entries become Sent events; a refusal after an accepted one is an error.
  BatchEnd take_answers(const std::vector<link::StreamRequest>& batch, std::vector<JournalEvent>& events,
                        JournalError& error);
  // After an outage cut the last batch: the firmware's accepted counter in st says how many of its unanswered
  // entries were queued; it runs requests in order, so they are the first ones. Resolves them (Outage events,
  // Sent for those accepted), then reconciles with st.
  JournalError outage(const rbx1_status_resp& st, std::vector<JournalEvent>& events);
  // A fresh STATUS: entries completed (StepDone, and Step for the next head), entries flushed (sent() moves back).
  JournalError reconcile(const rbx1_status_resp& st, std::vector<JournalEvent>& events);
  // Announces the head of the queue (Step) when it was sent and not announced yet.
  void announce(std::vector<JournalEvent>& events);
  // HEARTBEAT_LOST was cleared: the flushed entries will be sent again. Returns how many.
  size_t resend_flushed();

 private:
  void accept(std::vector<JournalEvent>& events);
  size_t since_base_accepted(const rbx1_status_resp& st) const;

  std::vector<std::string> names_;
  rbx1_status_resp base_;
  size_t accepted_ = 0;   // entries this job had accepted (A as the journal knows it)
  size_t sent_ = 0;       // next entry to send
  size_t done_ = 0;       // entries completed
  size_t announced_ = 0;  // entries whose start was reported
  size_t flushed_ = 0;    // entries flushed and not yet sent again
  uint8_t queue_free_ = 0;
  std::vector<link::StreamRequest> batch_;  // the last batch and its answers (outage() reads the unanswered)
  size_t batch_first_ = 0;
};

}  // namespace rbx1::daemon
