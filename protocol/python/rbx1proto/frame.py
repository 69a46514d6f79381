"""frame.py - RBX1 framing: CRC-32/ISO-HDLC, frame encoding and the resynchronising stream decoder (as the C one)."""
import zlib
from collections import namedtuple

SYNC = 0xA5
MAX_PAYLOAD = 58
OVERHEAD = 8  # SYNC LEN SEQ TYPE and the 4 CRC bytes
MAX_FRAME = MAX_PAYLOAD + OVERHEAD
BAD_CRC = 1     # = messages.Status.BAD_CRC (kept literal so framing does not depend on the message table)
BAD_LENGTH = 2  # = messages.Status.BAD_LENGTH

Frame = namedtuple("Frame", "seq type payload crc")
Reject = namedtuple("Reject", "status seq")  # seq is None when the SEQ byte was not read


def crc32(data):
    """CRC-32/ISO-HDLC (zlib's crc32): crc32(b'123456789') == 0xCBF43926."""
    return zlib.crc32(bytes(data)) & 0xFFFFFFFF


def encode(seq, type, payload=b""):
    """One frame: SYNC LEN SEQ TYPE PAYLOAD CRC (4 bytes, little-endian). ValueError if the payload exceeds 58 bytes."""
    payload = bytes(payload)
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    if not 0 <= seq <= 255 or not 0 <= type <= 255:
        raise ValueError("seq and type are bytes")
    body = bytes([len(payload), seq, type]) + payload
    return bytes([SYNC]) + body + crc32(body).to_bytes(4, "little")


class Decoder:
    """Streaming decoder. feed() returns the Frames and Rejects completed by the bytes, in stream order.
    After a rejection it resumes hunting at the byte after the rejected SYNC (see PROTOCOL.md)."""

    def __init__(self):
        self.buf = bytearray()

    def pending(self):
        """True while a frame has started but not completed."""
        return bool(self.buf)

    def reset(self):
        """Inter-byte timeout: drops the partial frame's SYNC and rescans the bytes after it. Returns (pending,
        items): whether a frame was pending, and the Frames/Rejects the rescan completed (see PROTOCOL.md)."""
        pending = bool(self.buf)
        out = []
        while self.buf:
            self._shift(1)
            self._settle(out)
        return pending, out

    def _shift(self, start):
        i = self.buf.find(SYNC, start)
        del self.buf[:len(self.buf) if i < 0 else i]

    def feed(self, data):
        out = []
        for b in bytes(data):
            if not self.buf and b != SYNC:
                continue
            self.buf.append(b)
            self._settle(out)
        return out

    def _settle(self, out):
        buf = self.buf
        while len(buf) >= 3:
            length, seq = buf[1], buf[2]
            if length > MAX_PAYLOAD:
                self._shift(1)
                out.append(Reject(BAD_LENGTH, seq))
                continue
            if len(buf) < length + OVERHEAD:
                return
            rx = int.from_bytes(buf[4 + length:OVERHEAD + length], "little")
            if crc32(buf[1:4 + length]) == rx:
                out.append(Frame(seq, buf[3], bytes(buf[4:4 + length]), rx))
                self._shift(length + OVERHEAD)
            else:
                self._shift(1)
                out.append(Reject(BAD_CRC, seq))
