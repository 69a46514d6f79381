/* crc_avr.c - CRC, Reed-Solomon parity and decoder cycles on the ATmega2560, for tools/bench/crc-avr: Timer1 at clk/1
 * around each call, results printed on UART0 as "name value" lines. Compiled with avr-gcc -Os against
 * protocol/src/rbx1_proto.c; the nibble-table CRC-32 and version 3's CRC-16 are here as the baselines of the
 * library's 256-entry table. */
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

/* The parity of d[0..n) (the frame's LEN..CRC: 7 + payload bytes), as a value for timed(). */
static uint32_t fec_parity(const uint8_t *d, size_t n) {
  uint8_t par[RBX1_FEC_BYTES];
  rbx1_fec_parity(d, n, par);
  return par[0] | ((uint32_t)par[1] << 8);
}

/* Locating over a codeword d[0..n) (LEN..PAR 1), and a call that does nothing: the cost of the call and the timer
 * reads, taken out of locate's figure. */
static uint32_t fec_locate(const uint8_t *d, size_t n) {
  uint8_t error = 0;
  return (uint32_t)rbx1_fec_locate(d, n, &error) ^ error;
}
static uint32_t nothing(const uint8_t *d, size_t n) {
  (void)d;
  return (uint32_t)n;
}
static uint8_t buf[RBX1_MAX_FRAME];

/* Cycles of one call on d[0..n) (the Timer1 reads' own cost taken out by the caller). */
static uint16_t timed_on(uint32_t (*fn)(const uint8_t *, size_t), const uint8_t *d, uint8_t n) {
  uint16_t t0, t1;
  TCNT1 = 0;
  t0 = TCNT1;
  sink = fn(d, n);
  t1 = TCNT1;
  return (uint16_t)(t1 - t0);
}
static uint16_t timed(uint32_t (*crc)(const uint8_t *, size_t), uint8_t n) { return timed_on(crc, buf, n); }

static void per_byte(const char *name, uint32_t (*crc)(const uint8_t *, size_t), uint8_t n) {
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

/* Timer1 overflows (every 65,536 cycles): a decoder call may take longer (the worst byte does). */
static volatile uint16_t overflows;
ISR(TIMER1_OVF_vect) { overflows++; }

/* Feeds wire[0..n) one byte per call; prints the mean and the most cycles one byte took (Timer1 and its overflow
 * count: each overflow adds its interrupt's few cycles, under 0.1 %). */
static void decode(const char *name, rbx1_decoder *d, const uint8_t *wire, uint8_t n) {
  uint32_t sum = 0, most = 0;
  for (uint8_t i = 0; i < n; i++) {
    uint16_t t0, t1;
    uint32_t c;
    cli();
    TCNT1 = 0;
    TIFR1 = _BV(TOV1);
    overflows = 0;
    sei();
    t0 = TCNT1;
    rbx1_decoder_feed(d, wire + i, 1);
    cli();
    t1 = TCNT1;
    c = ((uint32_t)overflows << 16) + (TIFR1 & _BV(TOV1) && t1 < 0x8000u ? 0x10000UL : 0) + t1 - t0;
    sei();
    sum += c;
    if (c > most) most = c;
  }
  cli();
  printf("%s_bytes %u mean_cycles %lu max_cycles %lu frames %u rejects %u\n", name, n, (unsigned long)(sum / n),
         (unsigned long)most, frames, rejects);
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
  TIMSK1 = _BV(TOIE1); /* counted in decode() */
  for (uint8_t i = 0; i < sizeof buf; i++) buf[i] = (uint8_t)(i * 37u + 11u);
  printf("check %08lx\n", (unsigned long)rbx1_crc32((const uint8_t *)"123456789", 9));
  /* The longest CRC'd body: LEN SEQ TYPE and 58 payload bytes; the longest parity'd one: that and the CRC. */
  per_byte("crc32_table256", rbx1_crc32, RBX1_MAX_PAYLOAD + 3);
  per_byte("crc32_nibble16", crc32_nibble, RBX1_MAX_PAYLOAD + 3);
  per_byte("crc16_v3", crc16_v3, RBX1_MAX_PAYLOAD + 3);
  per_byte("fec_parity", fec_parity, RBX1_MAX_PAYLOAD + 7);
  /* A MOVE frame, one byte at a time: the last byte runs the CRC. */
  for (uint8_t i = 0; i < sizeof payload; i++) payload[i] = (uint8_t)(i * 13u);
  n = rbx1_frame_encode(wire, sizeof wire, 7, RBX1_MSG_MOVE, payload, sizeof payload);
  rbx1_decoder_init(&d, on_frame, on_reject, 0);
  decode("move_frame", &d, wire, (uint8_t)n);
  /* rbx1_fec_locate over the MOVE frame's codeword (LEN..PAR 1, 35 bytes), intact and with one damaged byte (the
   * discrete-log lookups too), less the cost of an empty call. */
  {
    uint16_t empty = timed_on(nothing, wire + 1, (uint8_t)(n - 1));
    uint16_t intact = timed_on(fec_locate, wire + 1, (uint8_t)(n - 1));
    wire[10] ^= 0x5A;
    uint16_t damaged = timed_on(fec_locate, wire + 1, (uint8_t)(n - 1));
    printf("fec_locate_move_bytes %u intact_cycles %u damaged_cycles %u\n", (unsigned)(n - 1), intact - empty,
           damaged - empty);
    /* The same MOVE with that damaged byte, one byte at a time: the last parity byte corrects it. */
    frames = rejects = 0;
    rbx1_decoder_init(&d, on_frame, on_reject, 0);
    decode("move_corrected", &d, wire, (uint8_t)n);
  }
  /* The worst byte: a corrupt 68-byte candidate with an inner candidate (SYNC, a LEN that ends its parity at the
   * outer frame's end, SEQ) every 3 bytes: the last byte rejects the outer one (its syndromes) and every inner one,
   * each after its CRC and its syndromes. */
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
  /* The same with each candidate's SEQ chosen (last candidate first: a SEQ changes only the candidates before it)
   * so that its syndromes point at one byte: its corrected reading runs the CRC a second time. */
  for (int8_t i = RBX1_MAX_FRAME - RBX1_FRAME_OVERHEAD; i >= 0; i--) {
    uint8_t error;
    if (wire[i] != RBX1_SYNC) continue;
    for (uint16_t v = 0; v < 256; v++) {
      wire[i + 2] = (uint8_t)(v == RBX1_SYNC ? 0 : v);
      if (rbx1_fec_locate(wire + i + 1, (size_t)(RBX1_MAX_FRAME - i - 1), &error) > 0) break;
    }
  }
  frames = rejects = 0;
  rbx1_decoder_init(&d, on_frame, on_reject, 0);
  decode("nested_located", &d, wire, RBX1_MAX_FRAME);
  cli();
  sleep_cpu();
  return 0;
}
