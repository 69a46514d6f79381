"""frame.py - RBX1 framing: CRC-32/ISO-HDLC, frame encoding and the resynchronising stream decoder (as the C one)."""
import zlib
from collections import namedtuple

SYNC = 0xA5
MAX_PAYLOAD = 58
FEC_BYTES = 2
OVERHEAD = 10  # SYNC LEN SEQ TYPE, the 4 CRC bytes and the 2 parity bytes
MAX_FRAME = MAX_PAYLOAD + OVERHEAD
BAD_CRC = 1     # = messages.Status.BAD_CRC (kept literal so framing does not depend on the message table)
BAD_LENGTH = 2  # = messages.Status.BAD_LENGTH

Frame = namedtuple("Frame", "seq type payload crc")
Reject = namedtuple("Reject", "status seq")  # seq is None when the SEQ byte was not read


def crc32(data):
    """CRC-32/ISO-HDLC (zlib's crc32): crc32(b'123456789') == 0xCBF43926."""
    return zlib.crc32(bytes(data)) & 0xFFFFFFFF


def _times2(x):
    """x * 2 in GF(2^8) with the polynomial 0x11D."""
    x <<= 1
    return (x ^ 0x11D) if x & 0x100 else x


_LOG = [0] * 256
_x = 1
for _i in range(255):
    _LOG[_x] = _i
    _x = _times2(_x)


def fec_parity(data):
    """The 2 Reed-Solomon parity bytes of data (generator (x + 1)(x + 2) = x^2 + 3x + 2 over GF(2^8), 0x11D)."""
    hi = lo = 0
    for b in bytes(data):
        f = b ^ hi
        hi, lo = lo ^ _times2(f) ^ f, _times2(f)
    return bytes([hi, lo])


def fec_locate(code):
    """A codeword (data then its parity): None when its syndromes show no error, -1 when one damaged byte cannot
    explain them, else (i, error): code[i] ^ error is the byte sent."""
    s0 = s1 = 0
    for b in bytes(code):
        s0 ^= b
        s1 = _times2(s1) ^ b
    if s0 == 0 and s1 == 0:
        return None
    if s0 == 0 or s1 == 0:
        return -1
    power = (_LOG[s1] - _LOG[s0]) % 255
    if power >= len(code):
        return -1
    return len(code) - 1 - power, s0


def encode(seq, type, payload=b""):
    """One frame: SYNC LEN SEQ TYPE PAYLOAD CRC (4 bytes, little-endian) PARITY (2 bytes). ValueError if the payload
    exceeds 58 bytes."""
    payload = bytes(payload)
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    if not 0 <= seq <= 255 or not 0 <= type <= 255:
        raise ValueError("seq and type are bytes")
    body = bytes([len(payload), seq, type]) + payload
    body += crc32(body).to_bytes(4, "little")
    return bytes([SYNC]) + body + fec_parity(body)


def implied_len(msg_type):
    """The payload length every frame of this TYPE has (requests and responses have fixed lengths), or -1: unknown
    types, and 0x7F (a NAK has 1 byte, a probe none)."""
    from . import messages  # the message table imports nothing from here; framing needs only these lengths
    if msg_type & 0x80:
        return messages.response_len(msg_type & 0x7F)
    return messages.request_len(msg_type)


class Decoder:
    """Streaming decoder. feed() returns the Frames and Rejects completed by the bytes, in stream order.
    A frame whose CRC holds is delivered at its last CRC byte (its parity is skipped when it comes); one whose CRC
    fails is read again with its parity (one byte corrected), then with the length its TYPE implies in place of
    LEN. The byte right after a delivered frame starts a candidate whatever its value, however late (a damaged
    SYNC; dropped silently if no reading holds, unless it is a real 0xA5: then rejected like any candidate). After a rejection it resumes hunting at the byte after the rejected SYNC (see
    PROTOCOL.md)."""

    def __init__(self):
        self.buf = bytearray()
        self.tried = 0  # the candidate's readings ending at or before this many bytes have been tried
        self.skip = 0   # parity bytes still to come of a frame delivered before them
        self.after = False  # the next byte follows a delivered frame: it starts a candidate whatever its value
        self.alt_end = self.last = 0  # the candidate's reading with its TYPE's length ends here (0: none); its last

    def pending(self):
        """True while a frame has started but not completed, or its parity bytes are still to come."""
        return bool(self.buf) or self.skip > 0

    def reset(self):
        """Inter-byte timeout: drops the partial frame's SYNC and rescans the bytes after it. Returns (pending,
        items): whether a frame was pending, and the Frames/Rejects the rescan completed (see PROTOCOL.md)."""
        pending = self.pending()
        out = []
        while self.buf:
            self._shift(1)
            self._settle(out)
        self.skip = 0  # parity that never came (a peer of version 4 sends none), also of a frame the rescan delivered
        self.after = False
        return pending, out

    def _shift(self, start):
        i = self.buf.find(SYNC, start)
        del self.buf[:len(self.buf) if i < 0 else i]
        self.tried = 0

    def feed(self, data):
        out = []
        for b in bytes(data):
            if self.skip:
                self.skip -= 1
                continue
            if not self.buf and b != SYNC and not self.after:
                continue
            self.after = False
            self.buf.append(b)
            self._settle(out)
        return out

    def _received_crc(self, length):
        return int.from_bytes(self.buf[4 + length:8 + length], "little")

    def _crc_holds(self, length):
        return crc32(self.buf[1:4 + length]) == self._received_crc(length)

    def _corrected_holds(self, length):
        found = fec_locate(self.buf[1:length + OVERHEAD])
        if found is None or found == -1 or found[0] == 0:  # at 0: LEN, which this reading took as read
            return False
        at, error = found
        self.buf[1 + at] ^= error
        if self._crc_holds(length):
            return True
        self.buf[1 + at] ^= error
        return False

    def _relength_holds(self, length):
        was, self.buf[1] = self.buf[1], length
        if fec_locate(self.buf[1:length + OVERHEAD]) is None and self._crc_holds(length):
            return True
        self.buf[1] = was
        return False

    def _deliver(self, length, out):
        buf = self.buf
        out.append(Frame(buf[2], buf[3], bytes(buf[4:4 + length]), self._received_crc(length)))
        if len(buf) > length + OVERHEAD:  # bytes after it (after a rescan) stay: the first starts a candidate
            del buf[:length + OVERHEAD]
        else:  # the next byte starts one; a frame delivered at its CRC has its parity still to come
            self.skip = length + OVERHEAD - len(buf)
            self.after = True
            del buf[:]
        self.tried = 0

    def _settle(self, out):
        buf = self.buf
        while len(buf) >= 4:
            length, seq = buf[1], buf[2]
            if self.tried < 4:  # a new candidate: where its readings end, worked out once
                alt = implied_len(buf[3])
                self.alt_end = alt + OVERHEAD if alt >= 0 and alt != length else 0
                self.last = max(length + OVERHEAD if length <= MAX_PAYLOAD else 0, self.alt_end)
            last = self.last
            delivered = False
            for end in range(self.tried + 1, min(len(buf), last) + 1):
                self.tried = end
                if length <= MAX_PAYLOAD and end == length + OVERHEAD - FEC_BYTES and self._crc_holds(length):
                    delivered = True
                elif length <= MAX_PAYLOAD and end == length + OVERHEAD and self._corrected_holds(length):
                    delivered = True
                elif end == self.alt_end and self._relength_holds(end - OVERHEAD):
                    delivered, length = True, end - OVERHEAD
                if delivered:
                    self._deliver(length, out)
                    break
            if delivered:
                continue
            if len(buf) < last:
                return
            synced = buf[0] == SYNC  # else the byte after a frame, taken for a damaged SYNC: dropped silently
            self._shift(1)
            if synced:
                out.append(Reject(BAD_CRC if length <= MAX_PAYLOAD else BAD_LENGTH, seq))
