"""link.py - a stop-and-wait RBX1 link over a serial port (pyserial): retransmission, SEQ tracking, HELLO."""
import time

from . import frame, messages
from .messages import MsgType

RESPONSE_BIT = 0x80
SLOW_TYPES = (MsgType.CONFIG_SET, MsgType.CONFIG_RESET)  # they write EEPROM: answered within 1 s (PROTOCOL.md)
SLOW_TIMEOUT = 1.0
INTER_BYTE_TIMEOUT = 0.05  # a partial frame older than this is dropped after a rescan (PROTOCOL.md)


class LinkError(Exception):
    """The firmware did not answer a request after every retransmission (the link is down)."""


class Link:
    """One request outstanding at a time. A request is sent, then retransmitted byte for byte (same SEQ) when no
    response arrives within `timeout` seconds or a NAK for its SEQ arrives, at most `retries` times."""

    def __init__(self, port, baudrate=115200, timeout=0.1, retries=5):
        import serial  # pyserial; imported here so framing and messages work without it
        self.ser = serial.Serial()
        self.ser.port = port
        self.ser.baudrate = baudrate
        self.ser.timeout = timeout
        self.ser.write_timeout = 1.0
        self.ser.open()
        _clear_hupcl(self.ser)
        self.timeout = timeout
        self.retries = retries
        self.seq = 0
        self.retransmissions = 0
        self.decoder = frame.Decoder()
        self.rejects = 0  # frames from the firmware that failed CRC/length checks
        self.clock = time.monotonic  # the timeout's clock (tests replace it)
        self.last_rx = 0.0  # when bytes last arrived (the inter-byte timeout)

    def close(self):
        self.ser.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def send_raw(self, data):
        """Writes bytes as they are (tests: garbage, corrupt frames)."""
        self.ser.write(bytes(data))
        self.ser.flush()

    def request(self, msg_type, **fields):
        """Sends one request and returns its response fields (status included). The SEQ is consumed whatever
        happens. Raises LinkError when all retransmissions went unanswered, ValueError on bad fields."""
        msg_type = MsgType(msg_type)
        seq = self.seq
        self.seq = (self.seq + 1) & 0xFF
        wire = frame.encode(seq, msg_type, messages.pack_request(msg_type, **fields))
        return self._exchange(msg_type, seq, wire)

    def hello(self):
        """HELLO handshake (send it first after connecting or reconnecting): numbering continues from the
        firmware's last_seq + 1, so no new request can look like a retransmission of its last one."""
        resp = self.request(MsgType.HELLO, proto_version=messages.PROTO_VERSION)
        self.seq = (resp["last_seq"] + 1) & 0xFF
        return resp

    def _exchange(self, msg_type, seq, wire):
        want = msg_type | RESPONSE_BIT
        wait = max(self.timeout, SLOW_TIMEOUT) if msg_type in SLOW_TYPES else self.timeout
        for attempt in range(self.retries + 1):
            if attempt:
                self.retransmissions += 1
            deadline = self.clock() + wait
            self.ser.write(wire)
            self.ser.flush()
            while True:
                # Read first, decide after: a process descheduled past the deadline still takes the response
                # that is already waiting instead of retransmitting (or giving up) needlessly.
                left = deadline - self.clock()
                self.ser.timeout = max(left, 0)
                data = self.ser.read(1) if left > 0 else b""
                data += self.ser.read(self.ser.in_waiting)
                if data:
                    now = self.clock()
                    events = []
                    if self.decoder.pending() and now - self.last_rx > INTER_BYTE_TIMEOUT:
                        events = self.decoder.reset()[1]  # a stale partial frame: rescanned, then dropped
                    self.last_rx = now
                    outcome = self._match(events + self.decoder.feed(data), want, seq)
                    if outcome == "nak":
                        break
                    if outcome is not None:
                        return outcome
                if left <= 0:
                    break
        raise LinkError(f"{msg_type.name} seq {seq}: no response after {self.retries} retransmissions")

    def _match(self, events, want, seq):
        """The response for (want, seq) as a dict, "nak" for a NAK of seq, None otherwise. Other frames (stale
        responses to earlier retransmissions, NAKs of other frames) are ignored."""
        nak = False
        for ev in events:
            if isinstance(ev, frame.Reject):
                self.rejects += 1
                continue
            if ev.seq != seq:
                continue
            if ev.type == want:
                try:
                    return messages.unpack_response(want & 0x7F, ev.payload)
                except ValueError as e:
                    raise LinkError(f"malformed response {want:#04x} seq {seq}: {e}") from None
            if ev.type == MsgType.NAK:
                nak = True
        return "nak" if nak else None


def _clear_hupcl(ser):
    """Keep DTR up when the port closes so that closing it does not reset an Arduino (PROTOCOL.md)."""
    try:
        import termios
        attrs = termios.tcgetattr(ser.fd)
        attrs[2] &= ~termios.HUPCL
        termios.tcsetattr(ser.fd, termios.TCSANOW, attrs)
    except (ImportError, OSError, AttributeError, TypeError):
        pass  # not a termios device (e.g. a socket URL): nothing to keep
