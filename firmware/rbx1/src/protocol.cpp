// protocol.cpp - link handling: decode, NAK, the window (order, at-most-once), dispatch, respond (PROTOCOL.md).
#include "protocol.h"

#include "commands.h"
#include "config.h"
#include "hal.h"
#include "rbx1_proto.h"
#include "rbx1_window.h"
#include "safety.h"

#include <string.h>

static rbx1_decoder decoder;
static rbx1_window window;
static uint8_t hello_last_seq = 0xFF;
static uint32_t last_byte_ms;

static void send(uint8_t seq, uint8_t type, const uint8_t *payload, uint8_t len) {
  uint8_t frame[RBX1_MAX_FRAME];
  size_t n = rbx1_frame_encode(frame, sizeof(frame), seq, type, payload, len);
  if (n) hal_serial_write(frame, (uint8_t)n);
}

static void send_nak(uint8_t seq, uint8_t reason) {
  rbx1_nak nak;
  uint8_t payload[RBX1_NAK_LEN];
  nak.reason = reason;
  send(seq, RBX1_MSG_NAK, payload, rbx1_nak_pack(&nak, payload));
}

// Executes a request in order (or refuses it with a status), remembers its answer and sends it.
static void run(const rbx1_frame *f) {
  uint8_t out[RBX1_MAX_PAYLOAD];
  uint8_t type = RBX1_RESPONSE(f->type), n;
  if (rbx1_request_len(f->type) != f->len) {
    // A known type with a wrong payload length: answered, not NAKed (resending the same bytes cannot help),
    // with a full-length response whose status is BAD_LENGTH; nothing is executed.
    n = (uint8_t)rbx1_response_len(f->type);
    for (uint8_t i = 0; i < n; i++) out[i] = 0;
    out[0] = RBX1_BAD_LENGTH;
  } else {
    n = cmd_execute(f, out);
  }
  rbx1_window_record(&window, f->seq, f->crc, type, out, n);
  send(f->seq, type, out, n);
}

static void on_frame(void *ctx, const rbx1_frame *f) {
  (void)ctx;
  if (rbx1_request_len(f->type) >= 0) safety_request_seen();  // any CRC-valid request, a duplicate included
  const rbx1_window_entry *dup = 0;
  switch (rbx1_window_accept(&window, f, &dup, &hello_last_seq)) {
    case RBX1_WIN_BYPASS: {
      // ESTOP: any CRC-valid frame of its TYPE stops the arm, whatever its payload length or SEQ (the safe reading
      // of a frame that is surely an e-stop); executed every time, never recorded. The requests held ahead of a
      // gap are dropped, never run: each is NAKed SEQ_GAP (a request before it is still missing) after the answer.
      uint8_t out[RBX1_ESTOP_RESP_LEN], seqs[RBX1_HELD_MAX];
      send(f->seq, RBX1_RESPONSE(f->type), out, cmd_execute(f, out));
      for (uint8_t i = 0, n = rbx1_window_drop_held(&window, seqs); i < n; i++) send_nak(seqs[i], RBX1_SEQ_GAP);
      return;
    }
    case RBX1_WIN_DUPLICATE:  // answered before: the same answer again, nothing executed
      send(f->seq, dup->type, dup->payload, dup->len);
      return;
    case RBX1_WIN_HELD:  // ahead of a missing request: kept (a copy: still kept once), run when the gap is filled
      send_nak(f->seq, RBX1_HELD);
      return;
    case RBX1_WIN_GAP:  // beyond the held range: the host resends in order
      send_nak(f->seq, RBX1_SEQ_GAP);
      return;
    case RBX1_WIN_OLD:  // older than the window, or a used SEQ with other bytes: never executed
      send_nak(f->seq, RBX1_SEQ_OLD);
      return;
    case RBX1_WIN_UNKNOWN:  // not a request type: NAKed, and no place in the order (its SEQ stays free)
      send_nak(f->seq, RBX1_UNKNOWN_TYPE);
      return;
    default:  // RBX1_WIN_NEW: the next in order (a HELLO has started a new session)
      break;
  }
  run(f);
  // The gap it filled may have held requests behind it: they run now, in SEQ order, each once.
  for (const rbx1_window_held *h; (h = rbx1_window_release(&window)) != 0;) {
    rbx1_frame g;
    g.seq = h->seq;
    g.type = h->type;
    g.len = h->len;
    g.crc = h->crc;
    memcpy(g.payload, h->payload, h->len < RBX1_MAX_REQ_LEN ? h->len : RBX1_MAX_REQ_LEN);
    run(&g);
  }
}

static void on_reject(void *ctx, uint8_t status, uint8_t seq, uint8_t has_seq) {
  (void)ctx;
  if (has_seq) send_nak(seq, status);
}

void protocol_init(void) {
  rbx1_decoder_init(&decoder, on_frame, on_reject, 0);
  rbx1_window_init(&window);
  last_byte_ms = hal_millis();
}

uint8_t protocol_last_seq(void) { return hello_last_seq; }

void protocol_poll(void) {
  uint32_t now = hal_millis();
  if (rbx1_decoder_pending(&decoder) && (uint32_t)(now - last_byte_ms) > FRAME_TIMEOUT_MS)
    rbx1_decoder_reset(&decoder);
  for (uint8_t i = 0; i < RBX1_MAX_FRAME; i++) {  // bounded, so the main loop keeps its pace
    int16_t c = hal_serial_read();
    if (c < 0) break;
    uint8_t b = (uint8_t)c;
    last_byte_ms = now;
    rbx1_decoder_feed(&decoder, &b, 1);
  }
}
