// dedup.h - at-most-once execution: remembers the SEQ and CRC of the last executed request and the response sent,
// so a retransmission gets the same response again without being executed twice (ESTOP is exempt).
#ifndef RBX1_DEDUP_H
#define RBX1_DEDUP_H

#include <stdint.h>

#include "rbx1_proto.h"

void dedup_init(void);
// 1 when frame is a retransmission of the last executed request; then *type/*payload/*len is the cached response.
uint8_t dedup_lookup(const rbx1_frame *frame, uint8_t *type, const uint8_t **payload, uint8_t *len);
// Records an executed request and its response.
void dedup_record(const rbx1_frame *frame, uint8_t type, const uint8_t *payload, uint8_t len);
// SEQ of the last executed request (HELLO.last_seq), 0xFF before any.
uint8_t dedup_last_seq(void);

#endif
