/* rbx1_window.h - the receiver's window (PROTOCOL.md "Window"): in-order execution, requests ahead of a gap held
 * (selective repeat), at-most-once execution over the last RBX1_WINDOW requests. C99, no heap; the firmware's link
 * and every simulator use it. */
#ifndef RBX1_WINDOW_H
#define RBX1_WINDOW_H

#include <stdint.h>

#include "rbx1_proto.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Requests a host may keep in flight, and requests (with their answers) the firmware remembers. HELLO reports it.
 * AVR RAM: RBX1_WINDOW * sizeof(rbx1_window_entry) + RBX1_HELD_MAX * sizeof(rbx1_window_held) + 4
 * = 8 * 47 + 7 * 34 + 4 = 618 bytes (the CRC is 4 bytes of each: 588 with version 3's CRC-16). */
#define RBX1_WINDOW 8
/* Requests held ahead of a gap: SEQ expect + 1 .. expect + RBX1_WINDOW - 1 (a host's window beyond the missing one). */
#define RBX1_HELD_MAX (RBX1_WINDOW - 1)

/* One remembered request: its SEQ and CRC, and the response that answered it. */
typedef struct {
  uint8_t seq;
  uint32_t crc;
  uint8_t type; /* the answer's TYPE */
  uint8_t len;  /* the answer's payload length */
  uint8_t payload[RBX1_MAX_RESP_LEN];
} rbx1_window_entry;

/* One request received ahead of a gap, not yet executed: the frame as it came (payload bytes beyond the longest
 * request are not kept: such a frame is answered BAD_LENGTH, which needs only its length). */
typedef struct {
  uint8_t used; /* 0: a free slot */
  uint8_t seq;
  uint32_t crc;
  uint8_t type;
  uint8_t len; /* the frame's payload length */
  uint8_t payload[RBX1_MAX_REQ_LEN];
} rbx1_window_held;

typedef struct {
  rbx1_window_entry entry[RBX1_WINDOW];
  rbx1_window_held held[RBX1_HELD_MAX];
  uint8_t count;  /* entries remembered, 0..RBX1_WINDOW */
  uint8_t newest; /* index of the newest entry when count > 0 */
  uint8_t expect; /* the next in-order SEQ */
  uint8_t synced; /* 0 after power-up: the first request is in order whatever its SEQ */
} rbx1_window;

/* What to do with a request (not ESTOP, which bypasses the window). */
enum {
  RBX1_WIN_NEW = 0,       /* the next in order: execute it, then rbx1_window_record() its answer */
  RBX1_WIN_DUPLICATE = 1, /* remembered (same SEQ and CRC): send the remembered answer again, execute nothing */
  RBX1_WIN_GAP = 2,       /* SEQ beyond the held range (RBX1_WINDOW..127 ahead): NAK SEQ_GAP, nothing changes */
  RBX1_WIN_OLD = 3,       /* behind it and not remembered: NAK SEQ_OLD, nothing changes */
  RBX1_WIN_BYPASS = 4,    /* ESTOP: executed and answered every time, outside the window */
  RBX1_WIN_UNKNOWN = 5,   /* not a request type: NAK UNKNOWN_TYPE, nothing changes (no place in the order) */
  RBX1_WIN_HELD = 6       /* 1..RBX1_WINDOW-1 ahead: held (a copy of a held one: kept as it was); NAK HELD, run later */
};

void rbx1_window_init(rbx1_window *w);
/* Classifies a request by its SEQ and CRC; for RBX1_WIN_DUPLICATE *dup points to the remembered entry. */
uint8_t rbx1_window_classify(const rbx1_window *w, uint8_t seq, uint32_t crc, const rbx1_window_entry **dup);
/* Records the answer of a RBX1_WIN_NEW request (the oldest entry is forgotten when full); the next expected SEQ
 * becomes seq + 1. len is clipped to RBX1_MAX_RESP_LEN. */
void rbx1_window_record(rbx1_window *w, uint8_t seq, uint32_t crc, uint8_t type, const uint8_t *payload, uint8_t len);
/* The receiver's decision for a CRC-valid frame: ESTOP (any payload) is RBX1_WIN_BYPASS (the caller then drops the
 * held requests: rbx1_window_drop_held); a TYPE that is not a request type (unknown ids, NAK, responses), whatever its
 * SEQ, is RBX1_WIN_UNKNOWN; a HELLO that is not a duplicate starts a new session (rbx1_window_restart; *last_seq is
 * then the SEQ answered before it) and is RBX1_WIN_NEW; a request 1..RBX1_WINDOW-1 ahead of the next expected SEQ
 * is held (RBX1_WIN_HELD; a copy of a held one is RBX1_WIN_HELD again, other bytes at a held SEQ RBX1_WIN_OLD);
 * any other frame is classified. */
uint8_t rbx1_window_accept(rbx1_window *w, const rbx1_frame *f, const rbx1_window_entry **dup, uint8_t *last_seq);
/* After a request in order was executed and recorded: the held request that is now next in order (taken out of the
 * hold; valid until the next rbx1_window_accept), or NULL. The caller executes and records it like a RBX1_WIN_NEW
 * one, and asks again until NULL, so the held requests run in SEQ order, each once. */
const rbx1_window_held *rbx1_window_release(rbx1_window *w);
/* ESTOP: forgets every held request, none executed; writes their SEQs in SEQ order into seqs (RBX1_HELD_MAX of
 * room) and returns how many (the firmware NAKs each SEQ_GAP: not run, a request before it is still missing). */
uint8_t rbx1_window_drop_held(rbx1_window *w, uint8_t *seqs);
/* A HELLO that is not a duplicate starts a new session: forgets every entry and every held request (none run); the
 * HELLO is then recorded (its SEQ sets the order). */
void rbx1_window_restart(rbx1_window *w);
/* SEQ of the newest recorded request (HELLO's last_seq), 0xFF when none since power-up. */
uint8_t rbx1_window_last_seq(const rbx1_window *w);

#ifdef __cplusplus
}
#endif
#endif
