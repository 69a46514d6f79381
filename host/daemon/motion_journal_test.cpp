// motion_journal_test.cpp - the journal's decisions, one table row per outage case the soak exercises (line faults,
// outages before/after a MOVE was accepted, vanished ports, daemon kills, power cycles): what was sent, what the
// firmware reports after it -> which entries are taken as accepted, sent again, or end the job.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <cstring>
#include <sstream>

#include "motion_journal.hpp"

namespace rbx1::daemon {
namespace {

// A row's script, operations separated by spaces:
//   b:ANSWERS  a batch of entries from sent() on, one character each for the answer the link returned:
//              o OK, q QUEUE_FULL, y BUSY, f FAULT_ACTIVE, n NOT_HOMED, x an answer with no payload, - none
//              (the row fails unless the batch is next_batch() long: the job always sends that many)
//   o:A/D/F/Q  the link failed under that batch; once back, STATUS counters (accepted/done/flushed since the
//              job's start, may be negative: a firmware that went back) and queue_free Q
//   s:A/D/F/Q  a STATUS polled (reconcile)
//   a          the job announces the head of the queue
//   r:N        HEARTBEAT_LOST cleared: N flushed entries are to be sent again
// events: the journal's events, 1-based like the job's: sentN, doneN, stepN (head started), outN+ / outN- (an
// unanswered entry resolved after an outage: accepted before it or not). end: the state after the last operation.
struct Row {
  const char* name;
  size_t steps;
  std::array<uint16_t, 4> base;  // the job's first STATUS: accepted, done, flushed counters, queue_free
  const char* script;
  const char* events;
  const char* end;    // "sent S done D flushed F free Q"
  const char* error;  // the error code that ends the script, or ""
};

const Row kRows[] = {
    // Line faults (corrupt, dropped, duplicated, delayed frames) are the link's to repair: the journal sees whole
    // answers, or a refusal when the queue was fuller than the last STATUS said.
    {"clean_run", 3, {0, 0, 0, 8}, "b:ooo a s:3/1/0/6 s:3/3/0/8",
     "sent1 sent2 sent3 step1 done1 step2 done2 step3 done3", "sent 3 done 3 flushed 0 free 8", ""},
    {"batches_follow_the_queue_room", 5, {0, 0, 0, 2}, "b:oo a s:2/1/0/1 b:o a s:3/3/0/2 b:oo a s:5/5/0/2",
     "sent1 sent2 step1 done1 step2 sent3 done2 step3 done3 sent4 sent5 step4 done4 step5 done5",
     "sent 5 done 5 flushed 0 free 2", ""},
    {"queue_full_refusal_waits_for_room", 3, {0, 0, 0, 8}, "b:oqq a s:1/0/0/7",
     "sent1 step1", "sent 1 done 0 flushed 0 free 7", ""},
    {"busy_and_fault_refusals_too", 3, {0, 0, 0, 8}, "b:oy- s:1/1/0/8 b:f-",
     "sent1 done1", "sent 1 done 1 flushed 0 free 0", ""},
    {"accepted_after_a_refusal_loses_the_order", 3, {0, 0, 0, 8}, "b:oqo", "sent1", "sent 1 done 0 flushed 0 free 0",
     "rejected"},
    {"refused_by_name", 3, {0, 0, 0, 8}, "b:on-", "sent1", "sent 1 done 0 flushed 0 free 7", "rejected"},
    {"answer_without_payload", 2, {0, 0, 0, 8}, "b:x-", "", "sent 0 done 0 flushed 0 free 8", "rejected"},
    // An outage (every byte lost both ways) or a vanished port under a batch: once the link is back the firmware's
    // accepted counter tells how many of the unanswered entries it queued, always a prefix.
    {"outage_before_the_move_was_accepted", 3, {0, 0, 0, 8}, "b:o-- o:1/0/0/7 b:oo a",
     "sent1 out2- sent2 sent3 step1", "sent 3 done 0 flushed 0 free 5", ""},
    // (Entry 1 completed before the job announced it, so no step is announced after: the job's events as they were.)
    {"outage_after_the_moves_were_accepted", 3, {0, 0, 0, 8}, "b:o-- o:3/1/0/6 a",
     "sent1 out2+ sent2 out3+ sent3 done1", "sent 3 done 1 flushed 0 free 6", ""},
    {"outage_between_two_moves", 3, {0, 0, 0, 8}, "b:o-- o:2/0/0/6 b:o",
     "sent1 out2+ sent2 out3- sent3", "sent 3 done 0 flushed 0 free 5", ""},
    {"outage_with_every_answer_lost", 3, {0, 0, 0, 8}, "b:--- o:0/0/0/8 b:ooo", "out1- sent1 sent2 sent3",
     "sent 3 done 0 flushed 0 free 5", ""},
    {"outage_answer_past_the_gap_agrees", 3, {0, 0, 0, 8}, "b:-o- o:2/0/0/6",
     "out1+ sent1 out2+ sent2 out3-", "sent 2 done 0 flushed 0 free 6", ""},
    {"outage_answer_past_the_gap_disagrees", 3, {0, 0, 0, 8}, "b:-o- o:0/0/0/8", "",
     "sent 0 done 0 flushed 0 free 8", "firmware_reset"},
    {"outage_counters_beyond_the_batch", 3, {0, 0, 0, 8}, "b:o-- o:5/0/0/3", "sent1",
     "sent 1 done 0 flushed 0 free 7", "firmware_reset"},
    {"outage_after_a_whole_batch_was_answered", 2, {0, 0, 0, 8}, "b:oo o:2/2/0/8", "sent1 sent2 done1 done2",
     "sent 2 done 2 flushed 0 free 8", ""},
    // The outage outlived the firmware's heartbeat: it stopped and flushed its queue; after CLEAR_FAULT the entries
    // that did not complete are sent again (absolute targets), the head announced again.
    {"heartbeat_lost_flushes_the_rest", 3, {0, 0, 0, 8}, "b:ooo a s:3/1/2/8 r:2 b:oo a s:5/3/2/8",
     "sent1 sent2 sent3 step1 done1 step2 sent2 sent3 step2 done2 step3 done3", "sent 3 done 3 flushed 0 free 8", ""},
    {"heartbeat_lost_inside_an_outage", 3, {0, 0, 0, 8}, "b:o-- o:1/0/1/8 r:1 b:ooo",
     "sent1 out2- sent1 sent2 sent3", "sent 3 done 0 flushed 0 free 5", ""},
    // Flushed with no fault is for the job to refuse (a STOP from elsewhere): the journal says how many.
    {"flushed_by_a_stop_from_elsewhere", 3, {0, 0, 0, 8}, "b:ooo a s:3/0/3/8", "sent1 sent2 sent3 step1",
     "sent 0 done 0 flushed 3 free 8", ""},
    // A daemon killed and restarted: the new job counts from the counters after stopping the dead daemon's entries
    // (whatever they were), across the 16-bit wrap.
    {"after_a_daemon_kill", 2, {500, 480, 20, 8}, "b:oo a s:2/2/0/8", "sent1 sent2 step1 done1 step2 done2",
     "sent 2 done 2 flushed 0 free 8", ""},
    {"counters_wrap", 3, {65534, 65533, 1, 8}, "b:ooo a s:3/3/0/8", "sent1 sent2 sent3 step1 done1 step2 done2 step3 done3",
     "sent 3 done 3 flushed 0 free 8", ""},
    // A firmware power-cycled or reset under the job: its counters no longer add up to what the job sent.
    {"power_cycle_seen_by_a_poll", 3, {100, 100, 0, 8}, "b:ooo a s:-100/-100/0/8", "sent1 sent2 sent3 step1",
     "sent 3 done 0 flushed 0 free 5", "firmware_reset"},
    {"power_cycle_during_an_outage", 3, {100, 100, 0, 8}, "b:o-- o:-100/-100/0/8", "sent1",
     "sent 1 done 0 flushed 0 free 7", "firmware_reset"},
    {"more_done_than_accepted", 2, {0, 0, 0, 8}, "b:oo s:2/3/0/8", "sent1 sent2", "sent 2 done 0 flushed 0 free 6",
     "firmware_reset"},
    {"accepted_without_being_sent", 2, {0, 0, 0, 8}, "b:o- o:1/0/0/7 s:2/0/0/6", "sent1 out2-",
     "sent 1 done 0 flushed 0 free 7", "firmware_reset"},
};

void PrintTo(const Row& row, std::ostream* os) { *os << row.name; }

std::string render(const std::vector<JournalEvent>& events) {
  std::string out;
  for (const JournalEvent& e : events) {
    if (!out.empty()) out += ' ';
    static const char* const kinds[] = {"sent", "done", "step", "out"};
    out += kinds[e.kind] + std::to_string(e.step + 1);
    if (e.kind == JournalEvent::Outage) out += e.accepted ? '+' : '-';
  }
  return out;
}

rbx1_status_resp status(const Row& row, const std::string& spec) {
  int a = 0, d = 0, f = 0, q = 0;
  EXPECT_EQ(std::sscanf(spec.c_str(), "%d/%d/%d/%d", &a, &d, &f, &q), 4) << spec;
  rbx1_status_resp st{};
  st.moves_accepted = uint16_t(row.base[0] + a);
  st.moves_done = uint16_t(row.base[1] + d);
  st.moves_flushed = uint16_t(row.base[2] + f);
  st.queue_free = uint8_t(q);
  return st;
}

std::vector<link::StreamRequest> answers(const std::string& spec, uint8_t queue_free) {
  std::vector<link::StreamRequest> batch(spec.size());
  for (size_t i = 0; i < spec.size(); ++i) {
    link::StreamRequest& r = batch[i];
    r.type = RBX1_MSG_MOVE;
    if (spec[i] == '-') continue;
    r.answered = true;
    if (spec[i] == 'x') continue;
    const char* codes = "oqyfn";
    const uint8_t status[] = {RBX1_OK, RBX1_QUEUE_FULL, RBX1_BUSY, RBX1_FAULT_ACTIVE, RBX1_NOT_HOMED};
    r.resp[0] = status[std::strchr(codes, spec[i]) - codes];
    r.resp[1] = r.resp[0] == RBX1_OK ? --queue_free : queue_free;
    r.resp_len = 2;
  }
  return batch;
}

class JournalTable : public testing::TestWithParam<Row> {};

TEST_P(JournalTable, Reproduces) {
  const Row& row = GetParam();
  std::vector<std::string> names;
  for (size_t i = 0; i < row.steps; ++i) names.push_back("s" + std::to_string(i + 1));
  rbx1_status_resp base{};
  base.moves_accepted = row.base[0];
  base.moves_done = row.base[1];
  base.moves_flushed = row.base[2];
  base.queue_free = uint8_t(row.base[3]);
  MotionJournal j(names, base);
  std::vector<JournalEvent> events;
  JournalError error;
  std::istringstream script(row.script);
  for (std::string op; !error && script >> op;) {
    const std::string arg = op.size() > 2 ? op.substr(2) : "";
    switch (op[0]) {
      case 'b':
        ASSERT_EQ(arg.size(), j.next_batch()) << op;
        j.take_answers(answers(arg, j.queue_free()), events, error);
        break;
      case 'o': error = j.outage(status(row, arg), events); break;
      case 's': error = j.reconcile(status(row, arg), events); break;
      case 'a': j.announce(events); break;
      case 'r': EXPECT_EQ(j.resend_flushed(), std::stoul(arg)) << op; break;
      default: FAIL() << "bad op " << op;
    }
  }
  EXPECT_EQ(render(events), row.events);
  std::ostringstream end;
  end << "sent " << j.sent() << " done " << j.done() << " flushed " << j.flushed() << " free " << int(j.queue_free());
  EXPECT_EQ(end.str(), row.end);
  EXPECT_EQ(error.code, row.error) << error.message;
  EXPECT_EQ(error.message.empty(), error.code.empty());
}

INSTANTIATE_TEST_SUITE_P(Outages, JournalTable, testing::ValuesIn(kRows),
                         [](const testing::TestParamInfo<Row>& info) { return std::string(info.param.name); });

// The messages the job shows, for the cases where the journal ends it.
TEST(MotionJournal, MessagesNameTheStepsAndCounters) {
  rbx1_status_resp base{};
  base.queue_free = 8;
  MotionJournal j({"approach", "descend", "grip"}, base);
  std::vector<JournalEvent> events;
  JournalError error;
  auto batch = answers("on-", 8);
  j.take_answers(batch, events, error);
  EXPECT_EQ(error.message, "firmware refused step 2 (descend): NOT_HOMED");

  MotionJournal k({"approach", "descend", "grip"}, base);
  JournalError none;
  k.take_answers(answers("o--", 8), events, none);
  rbx1_status_resp st = base;
  st.moves_accepted = 5;
  error = k.outage(st, events);
  EXPECT_EQ(error.message, "the firmware's counters (accepted 5 since the job began) disagree with the 1 entries "
                           "this job knows plus 2 unanswered; refusing to guess the arm's state");
}

}  // namespace
}  // namespace rbx1::daemon
