/* rbx1_window.c - the receiver's window: SEQ order, duplicates answered from memory, old frames refused. */
#include "rbx1_window.h"

#include <string.h>

void rbx1_window_init(rbx1_window *w) {
  w->count = 0;
  w->newest = 0;
  w->expect = 0;
  w->synced = 0;
}

uint8_t rbx1_window_classify(const rbx1_window *w, uint8_t seq, uint16_t crc, const rbx1_window_entry **dup) {
  uint8_t i;
  /* Remembered entries first: a retransmission of the newest one has SEQ expect - 1. */
  for (i = 0; i < w->count; i++) {
    const rbx1_window_entry *e = &w->entry[i];
    if (e->seq == seq && e->crc == crc) {
      *dup = e;
      return RBX1_WIN_DUPLICATE;
    }
  }
  if (!w->synced || seq == w->expect) return RBX1_WIN_NEW;
  /* Half the SEQ circle ahead is a gap (a request before it is missing), the other half is the past. */
  return (uint8_t)(seq - w->expect) < 128u ? RBX1_WIN_GAP : RBX1_WIN_OLD;
}

uint8_t rbx1_window_accept(rbx1_window *w, const rbx1_frame *f, const rbx1_window_entry **dup, uint8_t *last_seq) {
  uint8_t verdict;
  if (f->type == RBX1_MSG_ESTOP) return RBX1_WIN_BYPASS;
  /* Not a request: it takes no place in the order, so a host's next request may carry the same SEQ. */
  if (rbx1_request_len(f->type) < 0) return RBX1_WIN_UNKNOWN;
  verdict = rbx1_window_classify(w, f->seq, f->crc, dup);
  /* A HELLO is a retransmission only while it is the newest request remembered. Once others followed it, the same
     bytes are a new host's session that starts at the same SEQ (a tool run twice): answering it and the requests
     after it from memory would acknowledge requests never executed. */
  if (f->type == RBX1_MSG_HELLO && (verdict != RBX1_WIN_DUPLICATE || *dup != &w->entry[w->newest])) {
    *last_seq = rbx1_window_last_seq(w);
    rbx1_window_restart(w);
    return RBX1_WIN_NEW;
  }
  return verdict;
}

void rbx1_window_record(rbx1_window *w, uint8_t seq, uint16_t crc, uint8_t type, const uint8_t *payload, uint8_t len) {
  rbx1_window_entry *e;
  if (w->count == 0) {
    w->newest = 0;
    w->count = 1;
  } else {
    w->newest = (uint8_t)((w->newest + 1u) % RBX1_WINDOW);
    if (w->count < RBX1_WINDOW) w->count++;
  }
  e = &w->entry[w->newest];
  if (len > RBX1_MAX_RESP_LEN) len = RBX1_MAX_RESP_LEN;
  e->seq = seq;
  e->crc = crc;
  e->type = type;
  e->len = len;
  if (len) memcpy(e->payload, payload, len);
  w->expect = (uint8_t)(seq + 1u);
  w->synced = 1;
}

void rbx1_window_restart(rbx1_window *w) {
  w->count = 0;
  w->synced = 0;
}

uint8_t rbx1_window_last_seq(const rbx1_window *w) { return w->count ? w->entry[w->newest].seq : 0xFFu; }
