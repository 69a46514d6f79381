/* rbx1_window.h - the receiver's window (PROTOCOL.md "Window"): in-order acceptance and at-most-once execution
 * over the last RBX1_WINDOW requests. C99, no heap; the firmware's link and every simulator use it. */
#ifndef RBX1_WINDOW_H
#define RBX1_WINDOW_H

#include <stdint.h>

#include "rbx1_proto.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Requests a host may keep in flight, and requests (with their answers) the firmware remembers. HELLO reports it.
 * AVR RAM: RBX1_WINDOW * sizeof(rbx1_window_entry) + 4 = 8 * 45 + 4 = 364 bytes. */
#define RBX1_WINDOW 8

/* One remembered request: its SEQ and CRC, and the response that answered it. */
typedef struct {
  uint8_t seq;
  uint16_t crc;
  uint8_t type; /* the answer's TYPE */
  uint8_t len;  /* the answer's payload length */
  uint8_t payload[RBX1_MAX_RESP_LEN];
} rbx1_window_entry;

typedef struct {
  rbx1_window_entry entry[RBX1_WINDOW];
  uint8_t count;  /* entries held, 0..RBX1_WINDOW */
  uint8_t newest; /* index of the newest entry when count > 0 */
  uint8_t expect; /* the next in-order SEQ */
  uint8_t synced; /* 0 after power-up: the first request is in order whatever its SEQ */
} rbx1_window;

/* What to do with a request (not ESTOP, which bypasses the window). */
enum {
  RBX1_WIN_NEW = 0,       /* the next in order: execute it, then rbx1_window_record() its answer */
  RBX1_WIN_DUPLICATE = 1, /* remembered (same SEQ and CRC): send the remembered answer again, execute nothing */
  RBX1_WIN_GAP = 2,       /* SEQ ahead of the next expected one (1..127 ahead): NAK SEQ_GAP, nothing changes */
  RBX1_WIN_OLD = 3,       /* behind it and not remembered: NAK SEQ_OLD, nothing changes */
  RBX1_WIN_BYPASS = 4,    /* ESTOP: executed and answered every time, outside the window */
  RBX1_WIN_UNKNOWN = 5    /* not a request type: NAK UNKNOWN_TYPE, nothing changes (no place in the order) */
};

void rbx1_window_init(rbx1_window *w);
/* Classifies a request by its SEQ and CRC; for RBX1_WIN_DUPLICATE *dup points to the remembered entry. */
uint8_t rbx1_window_classify(const rbx1_window *w, uint8_t seq, uint16_t crc, const rbx1_window_entry **dup);
/* Records the answer of a RBX1_WIN_NEW request (the oldest entry is forgotten when full); the next expected SEQ
 * becomes seq + 1. len is clipped to RBX1_MAX_RESP_LEN. */
void rbx1_window_record(rbx1_window *w, uint8_t seq, uint16_t crc, uint8_t type, const uint8_t *payload, uint8_t len);
/* The receiver's decision for a CRC-valid frame: ESTOP (any payload) is RBX1_WIN_BYPASS; a TYPE that is not a
 * request type (unknown ids, NAK, responses), whatever its SEQ, is RBX1_WIN_UNKNOWN; a HELLO that is not a
 * duplicate starts a new session (rbx1_window_restart; *last_seq is then the SEQ answered before it) and is
 * RBX1_WIN_NEW; any other frame is classified. */
uint8_t rbx1_window_accept(rbx1_window *w, const rbx1_frame *f, const rbx1_window_entry **dup, uint8_t *last_seq);
/* A HELLO that is not a duplicate starts a new session: forgets every entry; the HELLO is then recorded (its SEQ
 * sets the order). */
void rbx1_window_restart(rbx1_window *w);
/* SEQ of the newest recorded request (HELLO's last_seq), 0xFF when none since power-up. */
uint8_t rbx1_window_last_seq(const rbx1_window *w);

#ifdef __cplusplus
}
#endif
#endif
