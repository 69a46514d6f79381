/* crc_avr.c - CRC and decoder cycles on the ATmega2560, for tools/bench/crc-avr: Timer1 at clk/1 around each call,
 * results printed on UART0 as "name value" lines. Compiled with avr-gcc -Os against protocol/src/rbx1_proto.c; the
 * nibble-table CRC-32 and version 3's CRC-16 are here as the baselines of the library's 256-entry table. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/pgmspace.h>
#include <avr/sleep.h>
#include <stdio.h>

#include "rbx1_proto.h"

static int put(char c, FILE *f) {
  (void)f;
  while (!(UCSR0A & _BV(UDRE0))) {
  }
  UDR0 = c;
  return 0;
}
static FILE out = FDEV_SETUP_STREAM(put, NULL, _FDEV_SETUP_WRITE);

static const uint32_t nibble[16] PROGMEM = {
    0x00000000UL, 0x1DB71064UL, 0x3B6E20C8UL, 0x26D930ACUL, 0x76DC4190UL, 0x6B6B51F4UL, 0x4DB26158UL, 0x5005713CUL,
    0xEDB88320UL, 0xF00F9344UL, 0xD6D6A3E8UL, 0xCB61B38CUL, 0x9B64C2B0UL, 0x86D3D2D4UL, 0xA00AE278UL, 0xBDBDF21CUL};

/* CRC-32/ISO-HDLC with a 16-entry table: two lookups per byte. */
static uint32_t crc32_nibble(const uint8_t *d, size_t n) {
  uint32_t crc = 0xFFFFFFFFUL;
  while (n--) {
    crc ^= *d++;
    crc = (crc >> 4) ^ pgm_read_dword(&nibble[crc & 15]);
    crc = (crc >> 4) ^ pgm_read_dword(&nibble[crc & 15]);
  }
  return ~crc;
}

/* Protocol version 3's CRC-16/CCITT-FALSE, table-free. */
static uint32_t crc16_v3(const uint8_t *d, size_t n) {
  uint16_t crc = 0xFFFFu;
  while (n--) {
    uint8_t x = (uint8_t)((crc >> 8) ^ *d++);
    x ^= (uint8_t)(x >> 4);
    crc = (uint16_t)((crc << 8) ^ ((uint16_t)x << 12) ^ ((uint16_t)x << 5) ^ x);
  }
  return crc;
}

volatile uint32_t sink;
static uint8_t buf[RBX1_MAX_FRAME];

/* Cycles of one call (the Timer1 reads' own cost taken out by the caller: the n = 0 call). */
static uint16_t timed(uint32_t (*crc)(const uint8_t *, size_t), uint8_t n) {
  uint16_t t0, t1;
  TCNT1 = 0;
  t0 = TCNT1;
  sink = crc(buf, n);
  t1 = TCNT1;
  return (uint16_t)(t1 - t0);
}

static void per_byte(const char *name, uint32_t (*crc)(const uint8_t *, size_t)) {
  const uint8_t n = RBX1_MAX_PAYLOAD + 3; /* the longest CRC'd body: LEN SEQ TYPE and 58 payload bytes */
  uint16_t c1 = timed(crc, 1), cn = timed(crc, n);
  printf("%s_cycles_per_byte %u.%02u\n", name, (cn - c1) / (n - 1), ((cn - c1) % (n - 1)) * 100u / (n - 1));
}

static uint16_t frames, rejects;
static void on_frame(void *ctx, const rbx1_frame *f) {
  (void)ctx;
  (void)f;
  frames++;
}
static void on_reject(void *ctx, uint8_t status, uint8_t seq, uint8_t has_seq) {
  (void)ctx;
  (void)status;
  (void)seq;
  (void)has_seq;
  rejects++;
}

/* Feeds wire[0..n) one byte per call; prints the mean and the most cycles one byte took. */
static void decode(const char *name, rbx1_decoder *d, const uint8_t *wire, uint8_t n) {
  uint32_t sum = 0;
  uint16_t most = 0;
  for (uint8_t i = 0; i < n; i++) {
    uint16_t t0, t1;
    TCNT1 = 0;
    t0 = TCNT1;
    rbx1_decoder_feed(d, wire + i, 1);
    t1 = TCNT1;
    sum += (uint16_t)(t1 - t0);
    if ((uint16_t)(t1 - t0) > most) most = (uint16_t)(t1 - t0);
  }
  printf("%s_bytes %u mean_cycles %lu max_cycles %u frames %u rejects %u\n", name, n, (unsigned long)(sum / n), most,
         frames, rejects);
}

int main(void) {
  static rbx1_decoder d;
  static uint8_t wire[RBX1_MAX_FRAME];
  uint8_t payload[26];
  size_t n;
  UCSR0B = _BV(TXEN0);
  stdout = &out;
  TCCR1A = 0;
  TCCR1B = _BV(CS10);
  for (uint8_t i = 0; i < sizeof buf; i++) buf[i] = (uint8_t)(i * 37u + 11u);
  printf("check %08lx\n", (unsigned long)rbx1_crc32((const uint8_t *)"123456789", 9));
  per_byte("crc32_table256", rbx1_crc32);
  per_byte("crc32_nibble16", crc32_nibble);
  per_byte("crc16_v3", crc16_v3);
  /* A MOVE frame, one byte at a time: the last byte runs the CRC. */
  for (uint8_t i = 0; i < sizeof payload; i++) payload[i] = (uint8_t)(i * 13u);
  n = rbx1_frame_encode(wire, sizeof wire, 7, RBX1_MSG_MOVE, payload, sizeof payload);
  rbx1_decoder_init(&d, on_frame, on_reject, 0);
  decode("move_frame", &d, wire, (uint8_t)n);
  /* The worst byte: a corrupt 66-byte candidate with an inner candidate (SYNC, a LEN that ends it at the outer
   * frame's end, SEQ) every 3 bytes: the last byte rejects the outer one and every inner one, each after its CRC. */
  wire[0] = RBX1_SYNC;
  wire[1] = RBX1_MAX_PAYLOAD;
  wire[2] = 0;
  for (uint8_t i = 3; i < RBX1_MAX_FRAME; i++) wire[i] = 0;
  for (uint8_t i = 3; i + RBX1_FRAME_OVERHEAD <= RBX1_MAX_FRAME; i += 3) {
    wire[i] = RBX1_SYNC;
    wire[i + 1] = (uint8_t)(RBX1_MAX_FRAME - i - RBX1_FRAME_OVERHEAD);
  }
  frames = rejects = 0;
  rbx1_decoder_init(&d, on_frame, on_reject, 0);
  decode("nested_corrupt", &d, wire, RBX1_MAX_FRAME);
  cli();
  sleep_cpu();
  return 0;
}
