// dedup.cpp - duplicate suppression cache: one entry, the last executed request.
#include "dedup.h"

#include <string.h>

static struct {
  uint8_t valid, seq, type, len;
  uint16_t crc;
  uint8_t payload[RBX1_STATUS_RESP_LEN];  // the longest response
} last;

void dedup_init(void) {
  last.valid = 0;
  last.seq = 0xFF;
}

uint8_t dedup_lookup(const rbx1_frame *f, uint8_t *type, const uint8_t **payload, uint8_t *len) {
  if (!last.valid || f->seq != last.seq || f->crc != last.crc) return 0;
  *type = last.type;
  *payload = last.payload;
  *len = last.len;
  return 1;
}

void dedup_record(const rbx1_frame *f, uint8_t type, const uint8_t *payload, uint8_t len) {
  if (len > sizeof(last.payload)) len = sizeof(last.payload);
  last.valid = 1;
  last.seq = f->seq;
  last.crc = f->crc;
  last.type = type;
  last.len = len;
  memcpy(last.payload, payload, len);
}

uint8_t dedup_last_seq(void) { return last.seq; }
