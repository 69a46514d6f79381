"""link.py - an RBX1 link over a serial port (pyserial): requests one at a time or a stream with a window of them in
flight (selective repeat: requests held ahead of a lost one are not resent), SEQ tracking, HELLO."""
import binascii
import os
import select
import time

from . import frame, messages
from .messages import MsgType, Status
from .sender import AHEAD, SLOW_TIMEOUT, SLOW_TYPES, Sender

RESPONSE_BIT = 0x80
INTER_BYTE_TIMEOUT = 0.05  # a partial frame older than this is dropped after a rescan (PROTOCOL.md)
WRITE_STALL = 1.0  # a port that takes no byte for this long (a device that stopped reading): LinkError
PROBE_TYPE = MsgType.NAK  # a probe: a frame of no request type, NAKed UNKNOWN_TYPE in order (PROTOCOL.md "Probe")


class LinkError(Exception):
    """The firmware did not answer a request after every retransmission (the link is down)."""


def has_v3_frame(data):
    """Whether data holds a frame a protocol version 3 firmware sends (a NAK or a response: CRC-16/CCITT-FALSE,
    6 bytes of framing). Such a firmware NAKs our HELLO BAD_CRC in frames our decoder cannot read."""
    for i in range(len(data) - 5):
        n = data[i + 1]
        if data[i] != frame.SYNC or n > frame.MAX_PAYLOAD or i + n + 6 > len(data):
            continue
        if (data[i + 3] == MsgType.NAK or data[i + 3] & RESPONSE_BIT) and \
                binascii.crc_hqx(bytes(data[i + 1:i + n + 4]), 0xFFFF) == data[i + n + 4] | (data[i + n + 5] << 8):
            return True
    return False


class Link:
    """request(): one request outstanding; it is retransmitted byte for byte (same SEQ) when no response arrives
    within `timeout` seconds or a NAK for its SEQ arrives, at most `retries` times. stream(): many requests in order
    with up to the firmware's window in flight (PROTOCOL.md "Window")."""

    def __init__(self, port, baudrate=115200, timeout=0.1, retries=5, window=None):
        import serial  # pyserial; imported here so framing and messages work without it
        self.ser = serial.Serial()
        self.ser.port = port
        self.ser.baudrate = baudrate
        self.ser.timeout = timeout
        self.ser.open()
        _clear_hupcl(self.ser)
        self.timeout = timeout
        self.retries = retries
        self.seq = 0
        self.retransmissions = 0
        self.timeouts = 0  # stream(): silences that sent every unanswered request again
        self.probes = 0    # stream(): probes written (PROTOCOL.md "Probe")
        self.probe = True  # stream() writes probes (benchmarks turn them off for a baseline)
        self.fixed_timeout = False  # stream() times out after `timeout` alone, no line model (a benchmark baseline)
        self.causes = {}   # stream(): frames sent again, by what showed them lost (benchmarks print it)
        self.probes_answered = 0  # stream(): probes whose NAK came
        self.needless_timeouts = 0  # stream(): timeouts a probe's NAK came after, that probe written before them
        self.max_window = window  # a cap on the firmware's window (None: the firmware's)
        self.window = 1           # requests in flight in stream(): min(max_window, HELLO's window)
        self.ahead = AHEAD        # stream(): frames written beyond the last one an answer or NAK was about (0: the
                                  # whole window at once, a benchmark's baseline)
        self.baudrate = baudrate
        self.resync = False       # a stream failed: its lost SEQs would be gaps, the next stream starts with HELLO
        self.decoder = frame.Decoder()
        self.rejects = 0  # frames from the firmware that failed CRC/length checks
        self.clock = time.monotonic  # the timeout's clock (tests replace it)
        self.last_rx = 0.0  # when bytes last arrived (the inter-byte timeout)
        self.recent = None  # hello(): the bytes received, searched for a version 3 firmware's frames

    def close(self):
        self.ser.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def write(self, data):
        """Writes all of data to the port; LinkError when the port takes no byte for WRITE_STALL seconds. Not
        pyserial's write_timeout: pyserial 3.5 measures it from the call and checks it after the bytes went out, so
        a process descheduled that long during the call raised SerialTimeoutException with everything written (a
        9-byte HELLO in e2e_avrsim at load 18). Here only the port's own silence counts: select() rechecks the port
        when its timeout ends, however late this process runs again."""
        fd, view = self.ser.fileno(), memoryview(bytes(data))
        while view:
            try:
                n = os.write(fd, view)
            except BlockingIOError:
                n = 0
            if n:
                view = view[n:]
            elif not select.select([], [fd], [], WRITE_STALL)[1]:
                raise LinkError(f"{self.ser.port}: the port took no byte for {WRITE_STALL} s "
                                f"({len(view)} of {len(data)} left to write)")

    def send_raw(self, data):
        """Writes bytes as they are (tests: garbage, corrupt frames)."""
        self.write(data)
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
        """HELLO handshake (send it first after connecting or reconnecting): it starts a new session in the
        firmware's window, and numbering continues after the HELLO's own SEQ."""
        self.recent = bytearray()
        try:
            resp = self.request(MsgType.HELLO, proto_version=messages.PROTO_VERSION)
        except LinkError:
            if has_v3_frame(self.recent):
                raise LinkError(f"the firmware speaks protocol version 3 (CRC-16 frames: it NAKs every frame of ours), "
                                f"this host {messages.PROTO_VERSION}") from None
            raise
        finally:
            self.recent = None
        self.resync = False
        if resp["status"] == Status.OK:
            fw = max(1, resp["window"])
            self.window = min(fw, self.max_window) if self.max_window else fw
        return resp

    def stream(self, requests):
        """Sends [(msg_type, fields), ...] in order with up to self.window in flight and returns their responses (a
        list of dicts, in order). Retransmission (PROTOCOL.md "Window"): the firmware answers the frames it receives
        in order, so an event (an answer, or a NAK HELD/SEQ_GAP/UNKNOWN_TYPE: frames whose CRC held, so their SEQ is
        the request's; BAD_CRC and BAD_LENGTH NAKs are not counted) caused by one copy of a request shows that every
        unanswered request whose latest copy went out before that copy, and that is not held, has lost it (the frame
        or its answer): those are sent again at once, and so is a request NAKed SEQ_GAP/UNKNOWN_TYPE when the NAK is
        about its latest copy. A NAK HELD says the firmware holds that request and runs it once the gap before it is
        filled: it is not sent again (its answer comes when it runs; an answer of a held request says nothing of the
        others). Each event is attributed to a copy by counting (the k-th event naming a request comes from its k-th
        copy or a later one), never by timing. When the oldest unanswered request has had no answer by its deadline
        (PROTOCOL.md "Timeout": its latest copy's answer due on a model of the line at `baudrate`, plus a quarter of the
        timeout, doubled by each timeout since; never after the timeout), every unanswered one is sent again from the
        oldest, held ones included. The firmware answers those it had
        executed from its window, and held ones HELD again. A write after which nothing more can go out (the window
        full, or the stream's last request written) that carries resends or the last request is followed by a probe
        (PROTOCOL.md "Probe"): its NAK comes after the answers of every copy written before it, so a lost resend or a
        lost last request is sent again then, not after the timeout. Raises LinkError after `retries` resends of the
        oldest request without its answer, or on a NAK SEQ_OLD (resending cannot cure it)."""
        if self.resync:
            self.hello()
        frames = []
        for msg_type, fields in requests:
            msg_type = MsgType(msg_type)
            frames.append((msg_type, self.seq, frame.encode(self.seq, msg_type, messages.pack_request(msg_type, **fields))))
            self.seq = (self.seq + 1) & 0xFF
        s = Sender([t for t, _, _ in frames], [q for _, q, _ in frames], [len(w) for _, _, w in frames], self.window,
                   ahead=self.ahead, timeout=self.timeout, baudrate=self.baudrate, retries=self.retries,
                   probe=self.probe, fixed_timeout=self.fixed_timeout, counters=self)
        writes = s.start(self.clock())
        while True:
            for w in writes:
                self.write(b"".join(frames[i][2] for i in w.frames) +
                           (frame.encode(w.probe, PROBE_TYPE, b"") if w.probe is not None else b""))
            if s.finished:
                break
            for ev in self._read_events(s.deadline() - self.clock()):
                s.feed(ev)
            writes = s.step(self.clock())
        if s.error is not None:
            self.resync = True
            raise LinkError(s.error)
        return s.results

    def _read_events(self, left):
        """Frames and Rejects decoded from what arrives within `left` seconds (returns as soon as bytes arrive)."""
        self.ser.timeout = max(left, 0)
        data = self.ser.read(1) if left > 0 else b""
        data += self.ser.read(self.ser.in_waiting)
        if not data:
            return []
        now = self.clock()
        events = []
        if self.decoder.pending() and now - self.last_rx > INTER_BYTE_TIMEOUT:
            events = self.decoder.reset()[1]  # a stale partial frame: rescanned, then dropped
        self.last_rx = now
        return events + self.decoder.feed(data)

    def _exchange(self, msg_type, seq, wire):
        want = msg_type | RESPONSE_BIT
        wait = max(self.timeout, SLOW_TIMEOUT) if msg_type in SLOW_TYPES else self.timeout
        for attempt in range(self.retries + 1):
            if attempt:
                self.retransmissions += 1
            deadline = self.clock() + wait
            self.write(wire)
            self.ser.flush()
            while True:
                # Read first, decide after: a process descheduled past the deadline still takes the response
                # that is already waiting instead of retransmitting (or giving up) needlessly.
                left = deadline - self.clock()
                self.ser.timeout = max(left, 0)
                data = self.ser.read(1) if left > 0 else b""
                data += self.ser.read(self.ser.in_waiting)
                if data and self.recent is not None:
                    self.recent = (self.recent + data)[-128:]
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
            if ev.type == MsgType.NAK and ev.payload != messages.pack_nak(Status.HELD):
                nak = True  # HELD: the firmware keeps it until the gap before it is filled; wait for the answer
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
