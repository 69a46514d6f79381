// protocol.cpp - link handling: decode, NAK, at-most-once, dispatch, respond (PROTOCOL.md).
#include "protocol.h"

#include "commands.h"
#include "config.h"
#include "dedup.h"
#include "hal.h"
#include "rbx1_proto.h"
#include "safety.h"

static rbx1_decoder decoder;
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

static void on_frame(void *ctx, const rbx1_frame *f) {
  (void)ctx;
  int want = rbx1_request_len(f->type);
  if (want < 0) {
    send_nak(f->seq, RBX1_UNKNOWN_TYPE);
    return;
  }
  safety_request_seen();
  uint8_t type = RBX1_RESPONSE(f->type);
  uint8_t out[RBX1_MAX_PAYLOAD];
  // ESTOP: any CRC-valid frame of its TYPE stops the arm, whatever its payload length (the safe reading of a frame
  // that is surely an e-stop); executed every time, never recorded, so a retransmitted ESTOP acts again.
  if (f->type == RBX1_MSG_ESTOP) {
    send(f->seq, type, out, cmd_execute(f, out));
    return;
  }
  const uint8_t *cached;
  uint8_t cached_type, cached_len;
  if (dedup_lookup(f, &cached_type, &cached, &cached_len)) {
    send(f->seq, cached_type, cached, cached_len);
    return;
  }
  uint8_t n;
  if (want != f->len) {
    // A known type with a wrong payload length: answered, not NAKed (resending the same bytes cannot help),
    // with a full-length response whose status is BAD_LENGTH; nothing is executed.
    n = (uint8_t)rbx1_response_len(f->type);
    for (uint8_t i = 0; i < n; i++) out[i] = 0;
    out[0] = RBX1_BAD_LENGTH;
  } else {
    n = cmd_execute(f, out);
  }
  dedup_record(f, type, out, n);
  send(f->seq, type, out, n);
}

static void on_reject(void *ctx, uint8_t status, uint8_t seq, uint8_t has_seq) {
  (void)ctx;
  if (has_seq) send_nak(seq, status);
}

void protocol_init(void) {
  rbx1_decoder_init(&decoder, on_frame, on_reject, 0);
  last_byte_ms = hal_millis();
}

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
