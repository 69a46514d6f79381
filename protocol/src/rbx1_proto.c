/* rbx1_proto.c - RBX1 framing: CRC-32/ISO-HDLC, frame encoding and the resynchronising stream decoder. */
#include "rbx1_proto.h"

#include <string.h>

#ifdef __AVR__
#include <avr/pgmspace.h>
#define CRC_TABLE(t, i) pgm_read_dword(&(t)[i])
#else
#define PROGMEM
#define CRC_TABLE(t, i) ((t)[i])
#endif

/* The CRC-32 of each byte value (the reflected polynomial 0xEDB88320, 8 steps): 1 KiB, in flash on the AVR. One
 * lookup per byte: 35 cycles per byte on the ATmega2560, against 127 for a 16-entry nibble table (64 bytes, two
 * lookups and two 32-bit shifts by 4) and 52 for version 3's table-free CRC-16 (avr-gcc -Os, Timer1 at clk/1 under
 * simavr, over 61 bytes; PROTOCOL.md "Frame"). */
static const uint32_t crc32_table[256] PROGMEM = {
    0x00000000UL, 0x77073096UL, 0xEE0E612CUL, 0x990951BAUL, 0x076DC419UL, 0x706AF48FUL,
    0xE963A535UL, 0x9E6495A3UL, 0x0EDB8832UL, 0x79DCB8A4UL, 0xE0D5E91EUL, 0x97D2D988UL,
    0x09B64C2BUL, 0x7EB17CBDUL, 0xE7B82D07UL, 0x90BF1D91UL, 0x1DB71064UL, 0x6AB020F2UL,
    0xF3B97148UL, 0x84BE41DEUL, 0x1ADAD47DUL, 0x6DDDE4EBUL, 0xF4D4B551UL, 0x83D385C7UL,
    0x136C9856UL, 0x646BA8C0UL, 0xFD62F97AUL, 0x8A65C9ECUL, 0x14015C4FUL, 0x63066CD9UL,
    0xFA0F3D63UL, 0x8D080DF5UL, 0x3B6E20C8UL, 0x4C69105EUL, 0xD56041E4UL, 0xA2677172UL,
    0x3C03E4D1UL, 0x4B04D447UL, 0xD20D85FDUL, 0xA50AB56BUL, 0x35B5A8FAUL, 0x42B2986CUL,
    0xDBBBC9D6UL, 0xACBCF940UL, 0x32D86CE3UL, 0x45DF5C75UL, 0xDCD60DCFUL, 0xABD13D59UL,
    0x26D930ACUL, 0x51DE003AUL, 0xC8D75180UL, 0xBFD06116UL, 0x21B4F4B5UL, 0x56B3C423UL,
    0xCFBA9599UL, 0xB8BDA50FUL, 0x2802B89EUL, 0x5F058808UL, 0xC60CD9B2UL, 0xB10BE924UL,
    0x2F6F7C87UL, 0x58684C11UL, 0xC1611DABUL, 0xB6662D3DUL, 0x76DC4190UL, 0x01DB7106UL,
    0x98D220BCUL, 0xEFD5102AUL, 0x71B18589UL, 0x06B6B51FUL, 0x9FBFE4A5UL, 0xE8B8D433UL,
    0x7807C9A2UL, 0x0F00F934UL, 0x9609A88EUL, 0xE10E9818UL, 0x7F6A0DBBUL, 0x086D3D2DUL,
    0x91646C97UL, 0xE6635C01UL, 0x6B6B51F4UL, 0x1C6C6162UL, 0x856530D8UL, 0xF262004EUL,
    0x6C0695EDUL, 0x1B01A57BUL, 0x8208F4C1UL, 0xF50FC457UL, 0x65B0D9C6UL, 0x12B7E950UL,
    0x8BBEB8EAUL, 0xFCB9887CUL, 0x62DD1DDFUL, 0x15DA2D49UL, 0x8CD37CF3UL, 0xFBD44C65UL,
    0x4DB26158UL, 0x3AB551CEUL, 0xA3BC0074UL, 0xD4BB30E2UL, 0x4ADFA541UL, 0x3DD895D7UL,
    0xA4D1C46DUL, 0xD3D6F4FBUL, 0x4369E96AUL, 0x346ED9FCUL, 0xAD678846UL, 0xDA60B8D0UL,
    0x44042D73UL, 0x33031DE5UL, 0xAA0A4C5FUL, 0xDD0D7CC9UL, 0x5005713CUL, 0x270241AAUL,
    0xBE0B1010UL, 0xC90C2086UL, 0x5768B525UL, 0x206F85B3UL, 0xB966D409UL, 0xCE61E49FUL,
    0x5EDEF90EUL, 0x29D9C998UL, 0xB0D09822UL, 0xC7D7A8B4UL, 0x59B33D17UL, 0x2EB40D81UL,
    0xB7BD5C3BUL, 0xC0BA6CADUL, 0xEDB88320UL, 0x9ABFB3B6UL, 0x03B6E20CUL, 0x74B1D29AUL,
    0xEAD54739UL, 0x9DD277AFUL, 0x04DB2615UL, 0x73DC1683UL, 0xE3630B12UL, 0x94643B84UL,
    0x0D6D6A3EUL, 0x7A6A5AA8UL, 0xE40ECF0BUL, 0x9309FF9DUL, 0x0A00AE27UL, 0x7D079EB1UL,
    0xF00F9344UL, 0x8708A3D2UL, 0x1E01F268UL, 0x6906C2FEUL, 0xF762575DUL, 0x806567CBUL,
    0x196C3671UL, 0x6E6B06E7UL, 0xFED41B76UL, 0x89D32BE0UL, 0x10DA7A5AUL, 0x67DD4ACCUL,
    0xF9B9DF6FUL, 0x8EBEEFF9UL, 0x17B7BE43UL, 0x60B08ED5UL, 0xD6D6A3E8UL, 0xA1D1937EUL,
    0x38D8C2C4UL, 0x4FDFF252UL, 0xD1BB67F1UL, 0xA6BC5767UL, 0x3FB506DDUL, 0x48B2364BUL,
    0xD80D2BDAUL, 0xAF0A1B4CUL, 0x36034AF6UL, 0x41047A60UL, 0xDF60EFC3UL, 0xA867DF55UL,
    0x316E8EEFUL, 0x4669BE79UL, 0xCB61B38CUL, 0xBC66831AUL, 0x256FD2A0UL, 0x5268E236UL,
    0xCC0C7795UL, 0xBB0B4703UL, 0x220216B9UL, 0x5505262FUL, 0xC5BA3BBEUL, 0xB2BD0B28UL,
    0x2BB45A92UL, 0x5CB36A04UL, 0xC2D7FFA7UL, 0xB5D0CF31UL, 0x2CD99E8BUL, 0x5BDEAE1DUL,
    0x9B64C2B0UL, 0xEC63F226UL, 0x756AA39CUL, 0x026D930AUL, 0x9C0906A9UL, 0xEB0E363FUL,
    0x72076785UL, 0x05005713UL, 0x95BF4A82UL, 0xE2B87A14UL, 0x7BB12BAEUL, 0x0CB61B38UL,
    0x92D28E9BUL, 0xE5D5BE0DUL, 0x7CDCEFB7UL, 0x0BDBDF21UL, 0x86D3D2D4UL, 0xF1D4E242UL,
    0x68DDB3F8UL, 0x1FDA836EUL, 0x81BE16CDUL, 0xF6B9265BUL, 0x6FB077E1UL, 0x18B74777UL,
    0x88085AE6UL, 0xFF0F6A70UL, 0x66063BCAUL, 0x11010B5CUL, 0x8F659EFFUL, 0xF862AE69UL,
    0x616BFFD3UL, 0x166CCF45UL, 0xA00AE278UL, 0xD70DD2EEUL, 0x4E048354UL, 0x3903B3C2UL,
    0xA7672661UL, 0xD06016F7UL, 0x4969474DUL, 0x3E6E77DBUL, 0xAED16A4AUL, 0xD9D65ADCUL,
    0x40DF0B66UL, 0x37D83BF0UL, 0xA9BCAE53UL, 0xDEBB9EC5UL, 0x47B2CF7FUL, 0x30B5FFE9UL,
    0xBDBDF21CUL, 0xCABAC28AUL, 0x53B39330UL, 0x24B4A3A6UL, 0xBAD03605UL, 0xCDD70693UL,
    0x54DE5729UL, 0x23D967BFUL, 0xB3667A2EUL, 0xC4614AB8UL, 0x5D681B02UL, 0x2A6F2B94UL,
    0xB40BBE37UL, 0xC30C8EA1UL, 0x5A05DF1BUL, 0x2D02EF8DUL};

#define CRC32_STEP(crc, byte) (((crc) >> 8) ^ CRC_TABLE(crc32_table, (uint8_t)((uint8_t)(crc) ^ (byte))))

uint32_t rbx1_crc32_update(uint32_t crc, uint8_t byte) { return CRC32_STEP(crc, byte); }

uint32_t rbx1_crc32(const uint8_t *data, size_t n) {
  uint32_t crc = 0xFFFFFFFFUL;
  while (n--) crc = CRC32_STEP(crc, *data++); /* the step inline: a call per byte costs 20 cycles on the AVR */
  return ~crc;
}

/* Reed-Solomon parity (PROTOCOL.md "Frame"): GF(2^8) with the polynomial 0x11D, generator g(x) = (x + 1)(x + 2) =
 * x^2 + 3x + 2. Multiplying by 2 and 3 is a shift and an XOR, so encoding and the syndromes need no table; locating
 * an error takes one lookup in the discrete-log table below (256 bytes, in flash on the AVR). */
#define GF_TIMES2(x) ((uint8_t)(((x) << 1) ^ (((x) & 0x80u) ? 0x1Du : 0u)))

static const uint8_t gf_log[256] PROGMEM = {
      0,   0,   1,  25,   2,  50,  26, 198,   3, 223,  51, 238,  27, 104, 199,  75,
      4, 100, 224,  14,  52, 141, 239, 129,  28, 193, 105, 248, 200,   8,  76, 113,
      5, 138, 101,  47, 225,  36,  15,  33,  53, 147, 142, 218, 240,  18, 130,  69,
     29, 181, 194, 125, 106,  39, 249, 185, 201, 154,   9, 120,  77, 228, 114, 166,
      6, 191, 139,  98, 102, 221,  48, 253, 226, 152,  37, 179,  16, 145,  34, 136,
     54, 208, 148, 206, 143, 150, 219, 189, 241, 210,  19,  92, 131,  56,  70,  64,
     30,  66, 182, 163, 195,  72, 126, 110, 107,  58,  40,  84, 250, 133, 186,  61,
    202,  94, 155, 159,  10,  21, 121,  43,  78, 212, 229, 172, 115, 243, 167,  87,
      7, 112, 192, 247, 140, 128,  99,  13, 103,  74, 222, 237,  49, 197, 254,  24,
    227, 165, 153, 119,  38, 184, 180, 124,  17,  68, 146, 217,  35,  32, 137,  46,
     55,  63, 209,  91, 149, 188, 207, 205, 144, 135, 151, 178, 220, 252, 190,  97,
    242,  86, 211, 171,  20,  42,  93, 158, 132,  60,  57,  83,  71, 109,  65, 162,
     31,  45,  67, 216, 183, 123, 164, 118, 196,  23,  73, 236, 127,  12, 111, 246,
    108, 161,  59,  82,  41, 157,  85, 170, 251,  96, 134, 177, 187, 204,  62,  90,
    203,  89,  95, 176, 156, 169, 160,  81,  11, 245,  22, 235, 122, 117,  44, 215,
     79, 174, 213, 233, 230, 231, 173, 232, 116, 214, 244, 234, 168,  80,  88, 175,
};
#ifdef __AVR__
#define GF_LOG(x) pgm_read_byte(&gf_log[x])
#else
#define GF_LOG(x) (gf_log[x])
#endif

void rbx1_fec_parity(const uint8_t *data, size_t n, uint8_t parity[RBX1_FEC_BYTES]) {
  uint8_t hi = 0, lo = 0; /* the remainder of data(x) * x^2 divided by g(x) */
  while (n--) {
    uint8_t f = (uint8_t)(*data++ ^ hi), f2 = GF_TIMES2(f);
    hi = (uint8_t)(lo ^ f2 ^ f); /* lo + 3f */
    lo = f2;                     /* 2f */
  }
  parity[0] = hi;
  parity[1] = lo;
}

int rbx1_fec_locate(const uint8_t *code, size_t n, uint8_t *error) {
  uint8_t s0 = 0, s1 = 0; /* the codeword's values at x = 1 and x = 2 (Horner, first byte the highest power) */
  size_t i;
  int power;
  for (i = 0; i < n; i++) {
    s0 ^= code[i];
    s1 = (uint8_t)(GF_TIMES2(s1) ^ code[i]);
  }
  if (s0 == 0 && s1 == 0) return -1;
  if (s0 == 0 || s1 == 0) return -2; /* one error e at power k gives s0 = e and s1 = e * 2^k, both non-zero */
  power = (int)GF_LOG(s1) - (int)GF_LOG(s0);
  if (power < 0) power += 255;
  if ((size_t)power >= n) return -2;
  *error = s0;
  return (int)(n - 1 - (size_t)power);
}

size_t rbx1_frame_encode(uint8_t *out, size_t cap, uint8_t seq, uint8_t type, const uint8_t *payload, uint8_t len) {
  size_t total = (size_t)len + RBX1_FRAME_OVERHEAD;
  uint32_t crc;
  if (len > RBX1_MAX_PAYLOAD || out == NULL || cap < total || (len > 0 && payload == NULL)) return 0;
  out[0] = RBX1_SYNC;
  out[1] = len;
  out[2] = seq;
  out[3] = type;
  if (len > 0) memcpy(out + 4, payload, len);
  crc = rbx1_crc32(out + 1, (size_t)len + 3);
  out[4 + len] = (uint8_t)crc;
  out[5 + len] = (uint8_t)(crc >> 8);
  out[6 + len] = (uint8_t)(crc >> 16);
  out[7 + len] = (uint8_t)(crc >> 24);
  rbx1_fec_parity(out + 1, (size_t)len + 7, out + 8 + len);
  return total;
}

void rbx1_decoder_init(rbx1_decoder *d, rbx1_on_frame on_frame, rbx1_on_reject on_reject, void *ctx) {
  d->n = 0;
  d->tried = 0;
  d->skip = 0;
  d->after = 0;
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
  d->tried = 0;
}

/* The payload length every frame of this TYPE has (requests and responses have fixed lengths), or -1: unknown
 * types, and 0x7F (a NAK has 1 byte, a probe none). */
static int implied_len(uint8_t type) {
  return (type & 0x80u) ? rbx1_response_len((uint8_t)(type & 0x7Fu)) : rbx1_request_len(type);
}

/* The CRC a frame of payload length len in buf carries (little-endian after its payload). */
static uint32_t received_crc(const rbx1_decoder *d, uint8_t len) {
  const uint8_t *c = d->buf + 4 + len;
  return (uint32_t)c[0] | ((uint32_t)c[1] << 8) | ((uint32_t)c[2] << 16) | ((uint32_t)c[3] << 24);
}

/* 1 if buf holds a frame of payload length len whose CRC holds. */
static int crc_holds(const rbx1_decoder *d, uint8_t len) {
  return rbx1_crc32(d->buf + 1, (size_t)len + 3) == received_crc(d, len);
}

/* The frame read with its parity: one damaged byte after LEN is corrected (LEN itself was taken as read, so an
 * error located there contradicts this reading). The buffer keeps the correction only if the CRC then holds. */
static int corrected_holds(rbx1_decoder *d, uint8_t len) {
  uint8_t error;
  int at = rbx1_fec_locate(d->buf + 1, (size_t)len + 9, &error);
  if (at <= 0) return 0;
  d->buf[1 + at] ^= error;
  if (crc_holds(d, len)) return 1;
  d->buf[1 + at] ^= error;
  return 0;
}

/* The frame read with the length its TYPE implies in place of LEN (LEN the one damaged byte): its syndromes must
 * vanish and its CRC hold. The buffer keeps the new LEN only if they do. */
static int relength_holds(rbx1_decoder *d, uint8_t len) {
  uint8_t was = d->buf[1], error;
  d->buf[1] = len;
  if (rbx1_fec_locate(d->buf + 1, (size_t)len + 9, &error) == -1 && crc_holds(d, len)) return 1;
  d->buf[1] = was;
  return 0;
}

static void deliver(rbx1_decoder *d, uint8_t len) {
  rbx1_frame f;
  f.seq = d->buf[2];
  f.type = d->buf[3];
  f.len = len;
  f.crc = received_crc(d, len);
  memcpy(f.payload, d->buf + 4, len);
  if (d->n > len + RBX1_FRAME_OVERHEAD) { /* bytes after it (after a rescan) stay: the first starts a candidate */
    d->n = (uint8_t)(d->n - (len + RBX1_FRAME_OVERHEAD));
    memmove(d->buf, d->buf + len + RBX1_FRAME_OVERHEAD, d->n);
  } else { /* the next byte starts one; a frame delivered at its CRC has its parity still to come */
    d->skip = (uint8_t)(len + RBX1_FRAME_OVERHEAD - d->n);
    d->after = 1;
    d->n = 0;
  }
  d->tried = 0;
  if (d->on_frame) d->on_frame(d->ctx, &f);
}

/* Decides the candidate in buf as far as the bytes allow. A candidate has up to three readings, each tried once,
 * when its last byte is in: as sent (CRC at LEN+8 bytes), with one byte corrected (parity at LEN+10), and with the
 * length its TYPE implies in place of LEN (at that length + 10). The first that holds delivers the frame; when every
 * reading has failed, the candidate is rejected and the hunt resumes at the byte after its SYNC. Every pass either
 * returns or discards at least one byte for good, so the total work is bounded by the bytes fed. Afterwards n is
 * below the candidate's last reading's end <= RBX1_MAX_FRAME, so the next byte always fits. */
static void decoder_settle(rbx1_decoder *d) {
  for (;;) {
    uint8_t len, end, delivered = 0;
    if (d->n < 4) return; /* SYNC LEN SEQ TYPE */
    len = d->buf[1];
    if (d->tried < 4) { /* a new candidate: where its readings end, worked out once */
      int alt = implied_len(d->buf[3]);
      d->alt_end = (alt >= 0 && alt != (int)len) ? (uint8_t)(alt + RBX1_FRAME_OVERHEAD) : 0;
      d->last = len <= RBX1_MAX_PAYLOAD ? (uint8_t)(len + RBX1_FRAME_OVERHEAD) : 0;
      if (d->alt_end > d->last) d->last = d->alt_end;
    }
    for (end = (uint8_t)(d->tried + 1); end <= d->n && end <= d->last; end++) {
      d->tried = end;
      if (len <= RBX1_MAX_PAYLOAD && end == len + (RBX1_FRAME_OVERHEAD - RBX1_FEC_BYTES) && crc_holds(d, len)) {
        delivered = 1;
      } else if (len <= RBX1_MAX_PAYLOAD && end == len + RBX1_FRAME_OVERHEAD && corrected_holds(d, len)) {
        delivered = 1;
      } else if (end == d->alt_end && relength_holds(d, (uint8_t)(end - RBX1_FRAME_OVERHEAD))) {
        delivered = 1;
        len = (uint8_t)(end - RBX1_FRAME_OVERHEAD);
      }
      if (delivered) {
        deliver(d, len);
        break;
      }
    }
    if (delivered) continue; /* the next candidate, if any, is in buf */
    if (d->n < d->last) return;
    {
      uint8_t synced = d->buf[0] == RBX1_SYNC, seq = d->buf[2]; /* not synced: the byte after a frame, taken for a
                                                                  * damaged SYNC, dropped silently */
      decoder_shift(d, 1); /* resume hunting at the byte after the rejected SYNC */
      if (synced && d->on_reject)
        d->on_reject(d->ctx, len <= RBX1_MAX_PAYLOAD ? RBX1_BAD_CRC : RBX1_BAD_LENGTH, seq, 1);
    }
  }
}

void rbx1_decoder_feed(rbx1_decoder *d, const uint8_t *data, size_t n) {
  size_t i;
  for (i = 0; i < n; i++) {
    if (d->skip) { /* a delivered frame's parity */
      d->skip--;
      continue;
    }
    if (d->n == 0 && data[i] != RBX1_SYNC && !d->after) continue; /* hunting */
    d->after = 0;
    d->buf[d->n++] = data[i];
    decoder_settle(d);
  }
}

int rbx1_decoder_reset(rbx1_decoder *d) {
  int pending = rbx1_decoder_pending(d);
  /* Every byte held is older than the timeout: drop the candidate's SYNC and scan the rest again, as after a
   * rejection, so a whole frame hidden inside is still delivered; a new candidate left incomplete is as stale, and
   * goes the same way. */
  while (d->n > 0) {
    decoder_shift(d, 1);
    decoder_settle(d);
  }
  d->skip = 0; /* parity that never came (a peer of version 4 sends none), also of a frame the rescan delivered */
  d->after = 0;
  return pending;
}

int rbx1_decoder_pending(const rbx1_decoder *d) { return d->n > 0 || d->skip > 0; }
