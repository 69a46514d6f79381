/* fuzz_decoder.c - libFuzzer target: the stream decoder under arbitrary bytes and chunkings, the receiver's window
 * fed with every decoded frame, every unpack, and an encoded frame with one damaged byte (it must decode intact). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "rbx1_proto.h"
#include "rbx1_window.h"

#define CHECK(cond) \
  do {              \
    if (!(cond)) abort(); \
  } while (0)

/* One decoding pass: checks each event's invariants and folds the events into a hash so that passes with
 * different chunkings can be compared. */
typedef struct {
  const uint8_t *stream;
  size_t stream_len;
  uint32_t hash;
  size_t events;
  rbx1_window win; /* the firmware's window, fed every frame */
} pass;


static void mix(pass *p, uint32_t v) { p->hash = (p->hash ^ v) * 16777619u; }

/* Held requests: each one 1..RBX1_WINDOW-1 ahead of the next expected SEQ, no SEQ twice. */
static void check_held(const rbx1_window *w) {
  uint8_t i, j;
  for (i = 0; i < RBX1_HELD_MAX; i++) {
    if (!w->held[i].used) continue;
    CHECK(w->synced);
    CHECK((uint8_t)(w->held[i].seq - w->expect) >= 1u && (uint8_t)(w->held[i].seq - w->expect) < RBX1_WINDOW);
    for (j = (uint8_t)(i + 1u); j < RBX1_HELD_MAX; j++) CHECK(!w->held[j].used || w->held[j].seq != w->held[i].seq);
  }
}

/* The window's invariants for one frame: a duplicate points to the remembered (SEQ, CRC); a new frame becomes the
 * newest entry and sets the order, then the held ones behind it run in SEQ order; a held one is 1..W-1 ahead; an
 * ESTOP drops every held one; nothing else changes the window. */
static void window_step(pass *p, const rbx1_frame *f) {
  const rbx1_window_entry *dup = NULL;
  uint8_t last = 0, before_count = p->win.count, before_expect = p->win.expect;
  uint8_t verdict = rbx1_window_accept(&p->win, f, &dup, &last);
  CHECK(verdict <= RBX1_WIN_HELD);
  CHECK((verdict == RBX1_WIN_UNKNOWN) == (rbx1_request_len(f->type) < 0));
  CHECK(p->win.count <= RBX1_WINDOW);
  if (verdict == RBX1_WIN_DUPLICATE) {
    CHECK(dup != NULL && dup->seq == f->seq && dup->crc == f->crc && dup->len <= RBX1_MAX_RESP_LEN);
  } else if (verdict == RBX1_WIN_NEW) {
    rbx1_window_record(&p->win, f->seq, f->crc, (uint8_t)(f->type | 0x80u), f->payload, f->len);
    CHECK(rbx1_window_last_seq(&p->win) == f->seq && p->win.expect == (uint8_t)(f->seq + 1u));
    CHECK(rbx1_window_classify(&p->win, f->seq, f->crc, &dup) == RBX1_WIN_DUPLICATE);
    for (const rbx1_window_held *h; (h = rbx1_window_release(&p->win)) != NULL;) {
      CHECK(h->seq == p->win.expect);
      rbx1_window_record(&p->win, h->seq, h->crc, (uint8_t)(h->type | 0x80u), h->payload,
                         h->len < RBX1_MAX_REQ_LEN ? h->len : RBX1_MAX_REQ_LEN);
      mix(p, 0x400u | h->seq);
    }
  } else if (verdict == RBX1_WIN_HELD) {
    uint8_t ahead = (uint8_t)(f->seq - p->win.expect);
    CHECK(p->win.count == before_count && p->win.expect == before_expect && ahead >= 1u && ahead < RBX1_WINDOW);
  } else if (verdict == RBX1_WIN_BYPASS) {
    uint8_t seqs[RBX1_HELD_MAX], n = rbx1_window_drop_held(&p->win, seqs), i;
    CHECK(n <= RBX1_HELD_MAX);
    for (i = 0; i < RBX1_HELD_MAX; i++) CHECK(!p->win.held[i].used);
    for (i = 1; i < n; i++) CHECK((uint8_t)(seqs[i] - p->win.expect) > (uint8_t)(seqs[i - 1] - p->win.expect));
  } else {
    CHECK(p->win.count == before_count && p->win.expect == before_expect);
  }
  check_held(&p->win);
  mix(p, 0x300u | verdict);
}

/* 1 if the encoded frame wire[0..m) was on the wire as one of the decoder's readings allows: its bytes after SYNC
 * up to the CRC as sent (the parity after them, if any, unread), or all m bytes after SYNC with at most one damaged.
 * SYNC itself may be any byte: the byte right after a delivered frame is read as a SYNC whatever its value. */
static int was_on_wire(const uint8_t *hay, size_t n, const uint8_t *wire, size_t m) {
  size_t i, k;
  for (i = 0; i + m - RBX1_FEC_BYTES <= n; i++) {
    size_t diff = 0;
    if (memcmp(hay + i + 1, wire + 1, m - RBX1_FEC_BYTES - 1) == 0) return 1;
    if (i + m > n) continue;
    for (k = 1; k < m && diff < 2; k++) diff += hay[i + k] != wire[k];
    if (diff < 2) return 1;
  }
  return 0;
}

static void on_frame(void *ctx, const rbx1_frame *f) {
  pass *p = (pass *)ctx;
  uint8_t wire[RBX1_MAX_FRAME];
  size_t n, i;
  CHECK(f->len <= RBX1_MAX_PAYLOAD);
  n = rbx1_frame_encode(wire, sizeof wire, f->seq, f->type, f->payload, f->len);
  CHECK(n == (size_t)f->len + RBX1_FRAME_OVERHEAD);
  CHECK(rbx1_crc32(wire + 1, n - 7) == f->crc); /* CRC valid */
  CHECK(((uint32_t)wire[n - 6] | ((uint32_t)wire[n - 5] << 8) | ((uint32_t)wire[n - 4] << 16) |
         ((uint32_t)wire[n - 3] << 24)) == f->crc);
  CHECK(was_on_wire(p->stream, p->stream_len, wire, n)); /* re-encodes to bytes that were on the wire */
  mix(p, 0x100u | f->seq);
  mix(p, f->type);
  mix(p, f->len);
  mix(p, f->crc);
  for (i = 0; i < f->len; i++) mix(p, f->payload[i]);
  window_step(p, f);
  p->events++;
}

static void on_reject(void *ctx, uint8_t status, uint8_t seq, uint8_t has_seq) {
  pass *p = (pass *)ctx;
  CHECK(status == RBX1_BAD_CRC || status == RBX1_BAD_LENGTH);
  CHECK(has_seq == 1);
  mix(p, 0x200u | status);
  mix(p, seq);
  p->events++;
}

/* Feeds the stream in chunks whose sizes cycle through sizes[]; size 0 means "inter-byte timeout" (reset). */
static void run_pass(pass *p, const uint8_t *sizes, size_t nsizes, int allow_reset) {
  rbx1_decoder d;
  size_t pos = 0, k = 0;
  rbx1_decoder_init(&d, on_frame, on_reject, p);
  while (pos < p->stream_len) {
    size_t n = nsizes ? sizes[k++ % nsizes] : p->stream_len;
    if (n == 0) {
      if (allow_reset) {
        rbx1_decoder_reset(&d);
        CHECK(!rbx1_decoder_pending(&d)); /* nothing is awaited after a timeout, parity included */
      }
      continue;
    }
    if (n > p->stream_len - pos) n = p->stream_len - pos;
    rbx1_decoder_feed(&d, p->stream + pos, n);
    pos += n;
    CHECK(d.n < RBX1_MAX_FRAME && d.skip <= RBX1_FEC_BYTES && (d.skip == 0 || d.n == 0));
    CHECK(rbx1_decoder_pending(&d) == (d.n > 0 || d.skip > 0));
  }
}

/* unpack(x) accepts exactly its length, and pack(unpack(x)) == x. */
#define FUZZ_CODEC(T, LEN)                                                        \
  do {                                                                            \
    T m;                                                                          \
    uint8_t out[RBX1_MAX_PAYLOAD];                                                \
    uint8_t len = (uint8_t)(size > 255 ? 255 : size);                             \
    uint8_t st = T##_unpack(&m, data, len);                                       \
    CHECK(st == (len == (LEN) ? RBX1_OK : RBX1_BAD_LENGTH));                      \
    if (st == RBX1_OK) {                                                          \
      CHECK(T##_pack(&m, out) == (LEN));                                          \
      CHECK(memcmp(out, data, (LEN)) == 0);                                       \
    }                                                                             \
  } while (0)

static void fuzz_unpack(const uint8_t *data, size_t size) {
  FUZZ_CODEC(rbx1_hello_req, RBX1_HELLO_REQ_LEN);
  FUZZ_CODEC(rbx1_hello_resp, RBX1_HELLO_RESP_LEN);
  FUZZ_CODEC(rbx1_status_resp, RBX1_STATUS_RESP_LEN);
  FUZZ_CODEC(rbx1_heartbeat_resp, RBX1_HEARTBEAT_RESP_LEN);
  FUZZ_CODEC(rbx1_move_req, RBX1_MOVE_REQ_LEN);
  FUZZ_CODEC(rbx1_move_resp, RBX1_MOVE_RESP_LEN);
  FUZZ_CODEC(rbx1_gripper_req, RBX1_GRIPPER_REQ_LEN);
  FUZZ_CODEC(rbx1_gripper_resp, RBX1_GRIPPER_RESP_LEN);
  FUZZ_CODEC(rbx1_home_req, RBX1_HOME_REQ_LEN);
  FUZZ_CODEC(rbx1_home_resp, RBX1_HOME_RESP_LEN);
  FUZZ_CODEC(rbx1_stop_resp, RBX1_STOP_RESP_LEN);
  FUZZ_CODEC(rbx1_estop_resp, RBX1_ESTOP_RESP_LEN);
  FUZZ_CODEC(rbx1_clear_fault_resp, RBX1_CLEAR_FAULT_RESP_LEN);
  FUZZ_CODEC(rbx1_enable_req, RBX1_ENABLE_REQ_LEN);
  FUZZ_CODEC(rbx1_enable_resp, RBX1_ENABLE_RESP_LEN);
  FUZZ_CODEC(rbx1_set_position_req, RBX1_SET_POSITION_REQ_LEN);
  FUZZ_CODEC(rbx1_set_position_resp, RBX1_SET_POSITION_RESP_LEN);
  FUZZ_CODEC(rbx1_config_get_req, RBX1_CONFIG_GET_REQ_LEN);
  FUZZ_CODEC(rbx1_config_get_resp, RBX1_CONFIG_GET_RESP_LEN);
  FUZZ_CODEC(rbx1_config_set_req, RBX1_CONFIG_SET_REQ_LEN);
  FUZZ_CODEC(rbx1_config_set_resp, RBX1_CONFIG_SET_RESP_LEN);
  FUZZ_CODEC(rbx1_config_reset_resp, RBX1_CONFIG_RESET_RESP_LEN);
  FUZZ_CODEC(rbx1_nak, RBX1_NAK_LEN);
  {
    int t;
    for (t = 0; t < 256; t++) {
      int rl = rbx1_request_len((uint8_t)t), sl = rbx1_response_len((uint8_t)t);
      CHECK(rl >= -1 && rl <= RBX1_MAX_PAYLOAD && sl >= -1 && sl <= RBX1_MAX_PAYLOAD && (rl < 0) == (sl < 0));
    }
  }
}

/* One damaged byte: a frame built from the input (SEQ, TYPE, and for a request or response TYPE its own payload
 * length), with the byte at a chosen position after SYNC XORed with a chosen non-zero value, decodes to exactly that
 * frame, in one chunk or byte by byte, with nothing left pending. The payload comes from a generator seeded by the
 * input: a payload the fuzzer wrote could hold a shorter frame that legitimately decodes first (readings are tried
 * in byte order). LEN is damaged only when TYPE has a fixed length, the one thing that can repair it. */
typedef struct {
  rbx1_frame got;
  int frames, rejects;
} one_frame;

static void one_on_frame(void *ctx, const rbx1_frame *f) {
  one_frame *o = (one_frame *)ctx;
  o->got = *f;
  o->frames++;
}

static void one_on_reject(void *ctx, uint8_t status, uint8_t seq, uint8_t has_seq) {
  (void)status;
  (void)seq;
  (void)has_seq;
  ((one_frame *)ctx)->rejects++;
}

static void fuzz_one_damaged_byte(const uint8_t *data, size_t size) {
  uint8_t payload[RBX1_MAX_PAYLOAD], wire[RBX1_MAX_FRAME], seq, type, error;
  uint32_t x = 2463534242u, crc;
  size_t n, pos, i, chunk;
  int len;
  if (size < 6) return;
  seq = data[0];
  type = data[1];
  len = (type & 0x80u) ? rbx1_response_len((uint8_t)(type & 0x7Fu)) : rbx1_request_len(type);
  if (len < 0) len = data[2] % (RBX1_MAX_PAYLOAD + 1);
  for (i = 5; i < size; i++) x = (x ^ data[i]) * 16777619u; /* the seed: the rest of the input */
  for (i = 0; i < (size_t)len; i++) {
    x ^= x << 13, x ^= x >> 17, x ^= x << 5; /* xorshift32 */
    payload[i] = (uint8_t)x;
  }
  n = rbx1_frame_encode(wire, sizeof wire, seq, type, payload, (uint8_t)len);
  CHECK(n == (size_t)len + RBX1_FRAME_OVERHEAD);
  crc = rbx1_crc32(wire + 1, (size_t)len + 3);
  pos = 1 + data[3] % (n - 1);
  if (pos == 1 && ((type & 0x80u) ? rbx1_response_len((uint8_t)(type & 0x7Fu)) : rbx1_request_len(type)) < 0) pos = 2;
  error = data[4] ? data[4] : 1;
  wire[pos] ^= error;
  for (chunk = 1; chunk <= n; chunk += n - 1) {
    one_frame o;
    rbx1_decoder d;
    memset(&o, 0, sizeof o);
    rbx1_decoder_init(&d, one_on_frame, one_on_reject, &o);
    for (i = 0; i < n; i += chunk) rbx1_decoder_feed(&d, wire + i, chunk < n - i ? chunk : n - i);
    CHECK(o.frames == 1 && o.rejects == 0 && !rbx1_decoder_pending(&d));
    CHECK(o.got.seq == seq && o.got.type == type && o.got.len == len && o.got.crc == crc);
    CHECK(memcmp(o.got.payload, payload, (size_t)len) == 0);
  }
}

/* Input: byte 0 = number of chunk-size bytes that follow (mod 16), then those sizes, then the stream. */
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  pass whole = {0}, chunked = {0}, reset = {0};
  const uint8_t *sizes;
  size_t nsizes, i, nonzero = 0;
  if (size == 0) return 0;
  nsizes = data[0] % 16u;
  if (nsizes > size - 1) nsizes = size - 1;
  sizes = data + 1;
  whole.stream = chunked.stream = reset.stream = data + 1 + nsizes;
  whole.stream_len = chunked.stream_len = reset.stream_len = size - 1 - nsizes;
  whole.hash = chunked.hash = reset.hash = 2166136261u;
  for (i = 0; i < nsizes; i++) nonzero += sizes[i] != 0;

  run_pass(&whole, NULL, 0, 0);
  CHECK(whole.events <= whole.stream_len); /* every event consumes at least one byte: bounded work */
  if (nonzero) {
    run_pass(&chunked, sizes, nsizes, 0); /* zeros skipped: the same bytes, other chunk boundaries */
    CHECK(chunked.events == whole.events && chunked.hash == whole.hash);
    run_pass(&reset, sizes, nsizes, 1); /* with inter-byte timeouts: invariants only */
  }
  fuzz_unpack(data, size);
  fuzz_one_damaged_byte(data, size);
  return 0;
}
