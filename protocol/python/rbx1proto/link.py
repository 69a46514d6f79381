"""link.py - an RBX1 link over a serial port (pyserial): requests one at a time or a stream with a window of them in
flight (selective repeat: requests held ahead of a lost one are not resent), SEQ tracking, HELLO."""
import binascii
import os
import select
import time

from . import frame, messages
from .messages import MsgType, Status

RESPONSE_BIT = 0x80
SLOW_TYPES = (MsgType.CONFIG_SET, MsgType.CONFIG_RESET)  # they write EEPROM: answered within 1 s (PROTOCOL.md)
SLOW_TIMEOUT = 1.0
INTER_BYTE_TIMEOUT = 0.05  # a partial frame older than this is dropped after a rescan (PROTOCOL.md)
AHEAD = 4  # stream(): frames on the line ahead of the answers (PROTOCOL.md "Pacing")
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
        n, win = len(frames), max(1, self.window)
        results = [None] * n
        sent_at = [0.0] * n      # the latest copy's time (the timeout of the slow types)
        due = [0.0] * n          # when the latest copy's answer is due on the line model (the timeout)
        answer = [frame.OVERHEAD + max(0, messages.response_len(t)) for t, _, _ in frames]  # answer bytes
        byte_time = 10.0 / self.baudrate if self.baudrate else 0.0
        line = [0.0, 0.0]        # when the bytes written so far are out: towards the firmware, and back
        txs = [[] for _ in range(n)]  # every copy's place in the order of all copies written
        events = [0] * n         # answers and NAKs naming the request (the k-th is about copy k or later)
        held = [False] * n       # the firmware said it holds the request (NAK HELD): not lost, not to resend
        release_copy = [0] * n   # the copy written because a held request's answer showed this one's answer lost
        by_release = set()       # requests to send again for that reason in this round
        probes = []              # (SEQ, copy number) of the probes written whose NAK has not come, oldest first
        tx = 0
        seen = 0                 # the latest copy an answer or NAK was about: the copies after it are on the line
        base = nxt = tries = silences = 0  # silences: timeouts since the oldest unanswered request changed
        oldest_since = 0.0
        last_timeout_tx = 0
        cause = {}

        def mark(i, why):
            again.add(i)
            cause.setdefault(i, why)

        def model(nbytes, back):
            """The line model (PROTOCOL.md "Timeout"): a frame written now arrives after the bytes written before it,
            and its answer goes back after it arrived and after the answers before it; returns when that answer is
            out."""
            line[0] += nbytes * byte_time
            line[1] = max(line[1], line[0]) + back * byte_time
            return line[1]

        def send(which, resent):
            nonlocal tx
            now = self.clock()
            line[0] = max(line[0], now)
            for i in which:
                tx += 1
                txs[i].append(tx)
                sent_at[i] = now
                due[i] = model(len(frames[i][2]), answer[i])
                if i in by_release:
                    release_copy[i] = tx
            by_release.clear()
            data = b"".join(frames[i][2] for i in which)
            # Nothing goes out after this write until answers come: a probe behind it shows what it lost.
            if self.probe and win > 1 and (resent or nxt == n) and (nxt == n or nxt - base >= win):
                tx += 1
                seq = (frames[base][1] - 1) & 0xFF  # never in flight: answered before the oldest unanswered one
                probes.append((seq, tx))
                data += frame.encode(seq, PROBE_TYPE, b"")
                model(frame.OVERHEAD, frame.OVERHEAD + 1)
                self.probes += 1
            self.write(data)

        def probe_answered(ev):
            """The copy number of the probe a NAK UNKNOWN_TYPE answers (the oldest written with its SEQ: the earliest
            it can be about; older probes still waiting were lost), else None."""
            if ev.type != MsgType.NAK or ev.payload != messages.pack_nak(Status.UNKNOWN_TYPE):
                return None
            for k, (seq, copy) in enumerate(probes):
                if seq == ev.seq:
                    del probes[:k + 1]
                    return copy
            return None

        def deadline(i, silences):
            """When silence about request i (the oldest unanswered) sends the window again (PROTOCOL.md "Timeout"): a
            quarter of the timeout, doubled by each silence since i became the oldest, after its latest copy's answer
            is due on the line model or after i became the oldest (a held request's answer follows the filler's),
            whichever is later, and never after the timeout; the slow types wait their own time."""
            if frames[i][0] in SLOW_TYPES:
                return sent_at[i] + max(self.timeout, SLOW_TIMEOUT)
            late = sent_at[i] + self.timeout
            if not byte_time or self.fixed_timeout:
                return late
            return min(late, max(due[i], oldest_since) + self.timeout / 4 * 2 ** silences)

        while base < n:
            # New requests go out as answers come back (PROTOCOL.md "Pacing"): a resend then waits behind a few
            # frames, not behind the whole window, and is answered before the window runs dry.
            room = min(n, base + win) - nxt
            if win > 1 and self.ahead:
                room = min(room, self.ahead - (tx - seen))
            if nxt < n and room > 0:
                fresh = list(range(nxt, nxt + room))
                nxt = fresh[-1] + 1
                send(fresh, False)
            again = set()
            cause.clear()
            for ev in self._read_events(deadline(base, silences) - self.clock()):
                if isinstance(ev, frame.Reject):
                    self.rejects += 1
                    continue
                copy = probe_answered(ev)
                if copy is not None:
                    seen = max(seen, copy)
                    self.probes_answered += 1
                    if copy < last_timeout_tx:
                        self.needless_timeouts += 1  # the answers were on their way: the line model was early
                    # Every unanswered request not held whose latest copy went out before the probe lost it.
                    for j in range(base, nxt):
                        if results[j] is None and not held[j] and txs[j][-1] < copy:
                            mark(j, "probe")
                    continue
                k = (ev.seq - frames[base][1]) & 0xFF
                if k >= nxt - base:
                    continue  # not in flight: a late copy of an earlier answer
                i = base + k
                if ev.type not in (MsgType.NAK, frames[i][0] | RESPONSE_BIT) or results[i] is not None:
                    continue  # stale: another type with this SEQ, or about a request already answered
                reason = None
                if ev.type == MsgType.NAK:
                    reason = messages.unpack_nak(ev.payload)["reason"] if len(ev.payload) == 1 else None
                    if reason not in (Status.HELD, Status.SEQ_GAP, Status.UNKNOWN_TYPE, Status.SEQ_OLD):
                        # BAD_CRC, BAD_LENGTH: its SEQ was read from damaged bytes and may name another request, so
                        # it is not counted; naming the oldest unanswered one it sends that again (at worst a copy
                        # answered from the firmware's memory).
                        if i == base:
                            mark(i, "bad_crc_nak")
                        continue
                events[i] += 1
                copy = txs[i][min(events[i], len(txs[i])) - 1]  # the earliest copy this event can be about
                if not (ev.type != MsgType.NAK and held[i]):  # a held request's answer is about no copy
                    seen = max(seen, copy)
                if ev.type == MsgType.NAK:
                    if reason == Status.SEQ_OLD:
                        self.resync = True
                        raise LinkError(f"{frames[i][0].name} seq {ev.seq}: NAK {Status(reason).name}")
                    held[i] = reason == Status.HELD  # a SEQ_GAP after HELD: the firmware dropped it (ESTOP)
                    if held[i]:
                        again.discard(i)
                    elif copy == txs[i][-1]:
                        mark(i, "refused")  # its latest copy was refused
                else:
                    try:
                        results[i] = messages.unpack_response(frames[i][0], ev.payload)
                    except ValueError as e:
                        raise LinkError(f"malformed response {ev.type:#04x} seq {ev.seq}: {e}") from None
                    again.discard(i)
                    # The firmware runs requests in SEQ order: every unanswered request before this one ran, and
                    # its answer (sent before this one) was lost. A held request's answer follows the answer of the
                    # request that filled the gap, not its own copy: it tells this, and nothing by copies.
                    for j in range(base, i):
                        # Not again for the other answers of the same release (they show nothing newer).
                        if results[j] is None and (held[j] or held[i]) and (held[j] or release_copy[j] != txs[j][-1]):
                            held[j] = False
                            mark(j, "release")
                            by_release.add(j)
                    if held[i]:
                        continue
                # Answers come in frame order: an unanswered request, not held, whose latest copy went out before
                # this copy lost it (the frame, or its answer).
                for j in range(base, nxt):
                    if j != i and results[j] is None and not held[j] and txs[j][-1] < copy:
                        mark(j, "answer" if ev.type != MsgType.NAK else "nak_" + Status(reason).name.lower())
            if results[base] is not None:
                while base < nxt and results[base] is not None:
                    base += 1
                tries = silences = 0
                oldest_since = self.clock()
                if base == nxt:
                    seen = tx  # every request written is answered: what was left on the line no longer counts
            if base == n:
                break
            again = sorted(j for j in again if results[j] is None)
            if not again and base < nxt and self.clock() >= deadline(base, silences):
                again = [i for i in range(base, nxt) if results[i] is None]  # silence: go back from the oldest
                self.timeouts += 1 if again else 0
                silences += 1
                last_timeout_tx = tx
                for i in again:
                    cause.setdefault(i, "timeout_probe_lost" if probes else "timeout_no_probe")
            if again:
                if again[0] == base:
                    tries += 1
                    if tries > self.retries:
                        self.resync = True
                        raise LinkError(f"{frames[base][0].name} seq {frames[base][1]}: no response after "
                                        f"{self.retries} retransmissions")
                self.retransmissions += len(again)
                for i in again:
                    why = cause.pop(i, "?")
                    self.causes[why] = self.causes.get(why, 0) + 1
                send(again, True)
        return results

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
