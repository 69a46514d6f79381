/* rbx1_window.c - the receiver's window: SEQ order, requests ahead of a gap held, duplicates answered from memory,
 * old frames refused. */
#include "rbx1_window.h"

#include <string.h>

void rbx1_window_init(rbx1_window *w) {
  uint8_t i;
  w->count = 0;
  w->newest = 0;
  w->expect = 0;
  w->synced = 0;
  for (i = 0; i < RBX1_HELD_MAX; i++) w->held[i].used = 0;
}

/* The held slot of a SEQ, or NULL. */
static rbx1_window_held *held_of(const rbx1_window *w, uint8_t seq) {
  uint8_t i;
  for (i = 0; i < RBX1_HELD_MAX; i++)
    if (w->held[i].used && w->held[i].seq == seq) return (rbx1_window_held *)&w->held[i];
  return NULL;
}

uint8_t rbx1_window_classify(const rbx1_window *w, uint8_t seq, uint32_t crc, const rbx1_window_entry **dup) {
  uint8_t i, ahead;
  const rbx1_window_held *h;
  /* Remembered entries first: a retransmission of the newest one has SEQ expect - 1. */
  for (i = 0; i < w->count; i++) {
    const rbx1_window_entry *e = &w->entry[i];
    if (e->seq == seq && e->crc == crc) {
      *dup = e;
      return RBX1_WIN_DUPLICATE;
    }
  }
  if (!w->synced || seq == w->expect) return RBX1_WIN_NEW;
  h = held_of(w, seq);
  if (h) return h->crc == crc ? RBX1_WIN_HELD : RBX1_WIN_OLD; /* other bytes at a held SEQ: a used SEQ */
  /* Up to W - 1 ahead is held (the rest of a host's window behind a missing request); further ahead, up to half
     the SEQ circle, is a gap; the other half is the past. */
  ahead = (uint8_t)(seq - w->expect);
  if (ahead < RBX1_WINDOW) return RBX1_WIN_HELD;
  return ahead < 128u ? RBX1_WIN_GAP : RBX1_WIN_OLD;
}

/* Keeps a request to run once the gap before it is filled. Every SEQ of the held range has a slot: at most
   RBX1_HELD_MAX SEQs are ahead within it, and a held one leaves its slot when it runs or is dropped. */
static void hold(rbx1_window *w, const rbx1_frame *f) {
  uint8_t i;
  for (i = 0; i < RBX1_HELD_MAX; i++) {
    rbx1_window_held *h = &w->held[i];
    if (h->used) continue;
    h->used = 1;
    h->seq = f->seq;
    h->crc = f->crc;
    h->type = f->type;
    h->len = f->len;
    memcpy(h->payload, f->payload, f->len < RBX1_MAX_REQ_LEN ? f->len : RBX1_MAX_REQ_LEN);
    return;
  }
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
  if (verdict == RBX1_WIN_HELD && !held_of(w, f->seq)) hold(w, f);
  return verdict;
}

const rbx1_window_held *rbx1_window_release(rbx1_window *w) {
  rbx1_window_held *h;
  if (!w->synced) return NULL;
  h = held_of(w, w->expect);
  if (h) h->used = 0; /* the bytes stay readable until the next hold */
  return h;
}

uint8_t rbx1_window_drop_held(rbx1_window *w, uint8_t *seqs) {
  uint8_t n = 0, ahead;
  rbx1_window_held *h;
  for (ahead = 1; ahead < RBX1_WINDOW; ahead++) {
    h = held_of(w, (uint8_t)(w->expect + ahead));
    if (!h) continue;
    h->used = 0;
    seqs[n++] = h->seq;
  }
  return n;
}

void rbx1_window_record(rbx1_window *w, uint8_t seq, uint32_t crc, uint8_t type, const uint8_t *payload, uint8_t len) {
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
  uint8_t i;
  w->count = 0;
  w->synced = 0;
  for (i = 0; i < RBX1_HELD_MAX; i++) w->held[i].used = 0;
}

uint8_t rbx1_window_last_seq(const rbx1_window *w) { return w->count ? w->entry[w->newest].seq : 0xFFu; }
