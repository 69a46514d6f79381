/* rbx1_proto.h - the RBX1 link protocol: framing, CRC, decoder, and message pack/unpack (see PROTOCOL.md).
 * C99, no heap, fixed buffers; compiled unchanged by avr-gcc for the firmware and by the host toolchain. */
#ifndef RBX1_PROTO_H
#define RBX1_PROTO_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define RBX1_PROTO_VERSION 5
#define RBX1_SYNC 0xA5
#define RBX1_MAX_PAYLOAD 58
#define RBX1_FRAME_OVERHEAD 10 /* SYNC LEN SEQ TYPE, 4 CRC bytes, 2 parity bytes */
#define RBX1_FEC_BYTES 2
#define RBX1_MAX_FRAME (RBX1_MAX_PAYLOAD + RBX1_FRAME_OVERHEAD)
#define RBX1_RESPONSE(type) ((uint8_t)((type) | 0x80u))

/* Message ids, status codes, states, bits and config keys: generated from messages.json. */
#include "rbx1_messages.h"

/* CRC-32/ISO-HDLC (zlib's crc32: poly 0x04C11DB7 reflected, init and xorout 0xFFFFFFFF); check("123456789") =
 * 0xCBF43926. rbx1_crc32_update steps the register alone: start from 0xFFFFFFFF, invert the end result. */
uint32_t rbx1_crc32_update(uint32_t crc, uint8_t byte);
uint32_t rbx1_crc32(const uint8_t *data, size_t n);

/* Reed-Solomon over GF(2^8) (polynomial 0x11D, generator (x + 1)(x + 2)): the 2 parity bytes that follow the CRC
 * and correct any one damaged byte from LEN to the last parity byte (PROTOCOL.md "Frame"). rbx1_fec_parity writes the
 * parity of data[0..n); rbx1_fec_locate takes a codeword (data then its parity, n <= 255 bytes) and returns -1 when
 * its syndromes show no error, -2 when one damaged byte cannot explain them, or the index i of the one damaged byte
 * (code[i] ^ *error is the byte sent). */
void rbx1_fec_parity(const uint8_t *data, size_t n, uint8_t parity[RBX1_FEC_BYTES]);
int rbx1_fec_locate(const uint8_t *code, size_t n, uint8_t *error);

/* Writes one frame into out (cap bytes). Returns the frame length, or 0 if len > RBX1_MAX_PAYLOAD or cap is too small. */
size_t rbx1_frame_encode(uint8_t *out, size_t cap, uint8_t seq, uint8_t type, const uint8_t *payload, uint8_t len);

/* One received, CRC-checked frame. crc identifies it for at-most-once execution. */
typedef struct {
  uint8_t seq;
  uint8_t type;
  uint8_t len;
  uint32_t crc;
  uint8_t payload[RBX1_MAX_PAYLOAD];
} rbx1_frame;

/* Called for each valid frame, and for each rejected one (status RBX1_BAD_CRC or RBX1_BAD_LENGTH; seq is the
 * rejected frame's SEQ when its header was read, has_seq says whether it was). */
typedef void (*rbx1_on_frame)(void *ctx, const rbx1_frame *frame);
typedef void (*rbx1_on_reject)(void *ctx, uint8_t status, uint8_t seq, uint8_t has_seq);

/* Streaming decoder: resynchronises after garbage and rescans the bytes of a rejected frame. */
typedef struct {
  uint8_t buf[RBX1_MAX_FRAME];
  uint8_t n;     /* bytes of the current candidate frame in buf, SYNC included */
  uint8_t tried; /* the candidate's readings that end at or before this many bytes have been tried */
  uint8_t skip;  /* parity bytes still to come of a frame delivered before them */
  uint8_t after; /* 1: the next byte follows a delivered frame, and starts a candidate whatever its value */
  uint8_t alt_end, last; /* the candidate's reading with its TYPE's length ends at alt_end bytes (0: none); the
                          * last of its readings at last (0: none, LEN above 58 and TYPE of no fixed length) */
  rbx1_on_frame on_frame;
  rbx1_on_reject on_reject;
  void *ctx;
} rbx1_decoder;

void rbx1_decoder_init(rbx1_decoder *d, rbx1_on_frame on_frame, rbx1_on_reject on_reject, void *ctx);
/* Feeds received bytes; callbacks run from inside this call, possibly several times. A frame whose CRC holds is
 * delivered at its last CRC byte (its 2 parity bytes are skipped when they come); one whose CRC fails is read again
 * with its parity (one byte corrected), then with the payload length its TYPE implies in place of LEN (a damaged
 * LEN). The byte right after a delivered frame starts a candidate whatever its value, however late (a damaged
 * SYNC); such a candidate is dropped silently if no reading holds, unless that byte is a real SYNC (then rejected). A rejection resumes the hunt at the byte after the rejected
 * SYNC; it is decided once the TYPE byte is in, so has_seq is 1 for every rejection this decoder reports. Work is bounded: each rejection discards at least one
 * byte, and costs at most three readings (a CRC each, and two syndromes over 67 bytes). Callbacks may call
 * rbx1_decoder_reset but must not feed the same decoder. */
void rbx1_decoder_feed(rbx1_decoder *d, const uint8_t *data, size_t n);
/* Inter-byte timeout: drops the partial frame's SYNC and rescans the bytes after it (a complete frame among them is
 * delivered through the callbacks; an incomplete rest is dropped too). Returns 1 if a frame was pending. */
int rbx1_decoder_reset(rbx1_decoder *d);
/* 1 while a frame has started but not completed, or its parity bytes are still to come. */
int rbx1_decoder_pending(const rbx1_decoder *d);

#ifdef __cplusplus
}
#endif
#endif
