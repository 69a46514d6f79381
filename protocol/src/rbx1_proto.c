/* rbx1_proto.c - RBX1 framing: CRC-16/CCITT-FALSE, frame encoding and the resynchronising stream decoder. */
#include "rbx1_proto.h"

#include <string.h>

uint16_t rbx1_crc16_update(uint16_t crc, uint8_t byte) {
  /* Byte-wise form of the 0x1021 polynomial: no table (saves AVR RAM), a handful of shifts per byte. */
  uint8_t x = (uint8_t)((crc >> 8) ^ byte);
  x ^= (uint8_t)(x >> 4);
  return (uint16_t)((crc << 8) ^ ((uint16_t)x << 12) ^ ((uint16_t)x << 5) ^ x);
}

uint16_t rbx1_crc16(const uint8_t *data, size_t n) {
  uint16_t crc = 0xFFFFu;
  size_t i;
  for (i = 0; i < n; i++) crc = rbx1_crc16_update(crc, data[i]);
  return crc;
}

size_t rbx1_frame_encode(uint8_t *out, size_t cap, uint8_t seq, uint8_t type, const uint8_t *payload, uint8_t len) {
  size_t total = (size_t)len + RBX1_FRAME_OVERHEAD;
  uint16_t crc;
  if (len > RBX1_MAX_PAYLOAD || out == NULL || cap < total || (len > 0 && payload == NULL)) return 0;
  out[0] = RBX1_SYNC;
  out[1] = len;
  out[2] = seq;
  out[3] = type;
  if (len > 0) memcpy(out + 4, payload, len);
  crc = rbx1_crc16(out + 1, (size_t)len + 3);
  out[4 + len] = (uint8_t)(crc & 0xFFu);
  out[5 + len] = (uint8_t)(crc >> 8);
  return total;
}

void rbx1_decoder_init(rbx1_decoder *d, rbx1_on_frame on_frame, rbx1_on_reject on_reject, void *ctx) {
  d->n = 0;
  d->on_frame = on_frame;
  d->on_reject = on_reject;
  d->ctx = ctx;
}

/* Discards buf[0..from) and any bytes up to the next SYNC, keeping the rest as the new candidate. */
static void decoder_shift(rbx1_decoder *d, uint8_t from) {
  uint8_t i = from;
  while (i < d->n && d->buf[i] != RBX1_SYNC) i++;
  if (i < d->n) memmove(d->buf, d->buf + i, (size_t)(d->n - i));
  d->n = (uint8_t)(d->n - i);
}

/* Decides the candidate(s) in buf as far as the bytes allow. Every pass either returns or discards at least one
 * byte for good, so the total work is bounded by the bytes fed (a rejection costs at most one CRC over 63 bytes).
 * Afterwards n < LEN+6 <= RBX1_MAX_FRAME, so the next byte always fits. */
static void decoder_settle(rbx1_decoder *d) {
  for (;;) {
    uint8_t len, seq;
    if (d->n < 3) return; /* SYNC LEN SEQ: BAD_LENGTH is reported with the SEQ so the sender can be NAKed */
    len = d->buf[1];
    seq = d->buf[2];
    if (len > RBX1_MAX_PAYLOAD) {
      decoder_shift(d, 1); /* resume hunting at the byte after the rejected SYNC */
      if (d->on_reject) d->on_reject(d->ctx, RBX1_BAD_LENGTH, seq, 1);
      continue;
    }
    if (d->n < (uint8_t)(len + RBX1_FRAME_OVERHEAD)) return;
    {
      uint16_t rx = (uint16_t)(d->buf[4 + len] | ((uint16_t)d->buf[5 + len] << 8));
      if (rbx1_crc16(d->buf + 1, (size_t)len + 3) == rx) {
        rbx1_frame f;
        f.seq = seq;
        f.type = d->buf[3];
        f.len = len;
        f.crc = rx;
        memcpy(f.payload, d->buf + 4, len);
        decoder_shift(d, (uint8_t)(len + RBX1_FRAME_OVERHEAD)); /* bytes after it (after a rescan) stay */
        if (d->on_frame) d->on_frame(d->ctx, &f);
      } else {
        decoder_shift(d, 1);
        if (d->on_reject) d->on_reject(d->ctx, RBX1_BAD_CRC, seq, 1);
      }
    }
  }
}

void rbx1_decoder_feed(rbx1_decoder *d, const uint8_t *data, size_t n) {
  size_t i;
  for (i = 0; i < n; i++) {
    if (d->n == 0 && data[i] != RBX1_SYNC) continue; /* hunting */
    d->buf[d->n++] = data[i];
    decoder_settle(d);
  }
}

int rbx1_decoder_reset(rbx1_decoder *d) {
  int pending = d->n > 0;
  /* Every byte held is older than the timeout: drop the candidate's SYNC and scan the rest again, as after a
   * rejection, so a whole frame hidden inside is still delivered; a new candidate left incomplete is as stale, and
   * goes the same way. */
  while (d->n > 0) {
    decoder_shift(d, 1);
    decoder_settle(d);
  }
  return pending;
}

int rbx1_decoder_pending(const rbx1_decoder *d) { return d->n > 0; }
