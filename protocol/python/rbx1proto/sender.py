"""sender.py - the window sender of Link.stream (PROTOCOL.md "Window", "Probe", "Pacing", "Timeout") as state and
steps without I/O: it is told the frames received and the time, and says what to write. The C++ sender
(host/link/window_sender.cpp) reproduces the same traces (protocol/vectors/sender_traces.json)."""
from . import frame, messages
from .messages import MsgType, Status

RESPONSE_BIT = 0x80
SLOW_TYPES = (MsgType.CONFIG_SET, MsgType.CONFIG_RESET)  # they write EEPROM: answered within 1 s (PROTOCOL.md)
SLOW_TIMEOUT = 1.0
AHEAD = 4  # frames on the line ahead of the answers (PROTOCOL.md "Pacing")


class Write:
    """One write: the requests whose frames go out, oldest first (indices), then a probe with SEQ `probe` or None."""

    def __init__(self, frames, probe=None):
        self.frames, self.probe = list(frames), probe

    def __eq__(self, other):
        return (self.frames, self.probe) == (other.frames, other.probe)

    def __repr__(self):
        return f"Write({self.frames}, probe={self.probe})"


class Counters:
    """What a stream counts (Link keeps these across streams)."""

    def __init__(self):
        self.retransmissions = self.timeouts = self.probes = self.rejects = 0
        self.probes_answered = self.needless_timeouts = 0
        self.causes = {}


class Sender:
    """Requests (types, SEQs, frame sizes) sent in order with up to `window` in flight. Retransmission (PROTOCOL.md
    "Window"): the firmware answers the frames it receives in order, so an event (an answer, or a NAK
    HELD/SEQ_GAP/UNKNOWN_TYPE: frames whose CRC held, so their SEQ is the request's; BAD_CRC and BAD_LENGTH NAKs are not
    counted) caused by one copy of a request shows that every unanswered request whose latest copy went out before that
    copy, and that is not held, has lost it (the frame or its answer): those are sent again at once, and so is a
    request NAKed SEQ_GAP/UNKNOWN_TYPE when the NAK is about its latest copy. A NAK HELD says the firmware holds that
    request and runs it once the gap before it is filled: it is not sent again (its answer comes when it runs; an
    answer of a held request says nothing of the others). Each event is attributed to a copy by counting (the k-th
    event naming a request comes from its k-th copy or a later one), never by timing. When the oldest unanswered
    request has had no answer by its deadline (PROTOCOL.md "Timeout"), every unanswered one is sent again from the
    oldest, held ones included. A write after which nothing more can go out (the window full, or the last request
    written) that carries resends or the last request is followed by a probe (PROTOCOL.md "Probe"). `error` is set
    (and nothing more is written) after `retries` resends of the oldest request without its answer, on a NAK SEQ_OLD
    (resending cannot cure it) or on a malformed answer."""

    def __init__(self, types, seqs, sizes, window, ahead=AHEAD, timeout=0.1, baudrate=115200, retries=5,
                 probe=True, fixed_timeout=False, counters=None):
        self.types = [MsgType(t) for t in types]
        self.seqs, self.sizes = list(seqs), list(sizes)
        self.n, self.win = len(self.types), max(1, window)
        self.ahead, self.timeout, self.retries = ahead, timeout, retries
        self.probe, self.fixed_timeout = probe, fixed_timeout
        self.counters = counters if counters is not None else Counters()
        self.byte_time = 10.0 / baudrate if baudrate else 0.0
        self.answer = [frame.OVERHEAD + max(0, messages.response_len(t)) for t in self.types]  # answer bytes
        self.results = [None] * self.n
        self.error = None        # why the stream ended unanswered (a LinkError's text)
        self.sent_at = [0.0] * self.n  # the latest copy's time (the timeout of the slow types)
        self.due = [0.0] * self.n      # when the latest copy's answer is due on the line model (the timeout)
        self.line = [0.0, 0.0]   # when the bytes written so far are out: towards the firmware, and back
        self.txs = [[] for _ in range(self.n)]  # every copy's place in the order of all copies written
        self.events = [0] * self.n  # answers and NAKs naming the request (the k-th is about copy k or later)
        self.held = [False] * self.n  # the firmware holds the request (NAK HELD): not lost, not to resend
        self.release_copy = [0] * self.n  # the copy written because a held request's answer showed its answer lost
        self.by_release = set()  # requests to send again for that reason in this round
        self.probes = []         # (SEQ, copy number) of the probes written whose NAK has not come, oldest first
        self.tx = 0
        self.seen = 0            # the latest copy an answer or NAK was about: the copies after it are on the line
        self.base = self.nxt = self.tries = self.silences = 0  # silences: timeouts since the oldest changed
        self.oldest_since = 0.0
        self.last_timeout_tx = 0
        self.again, self.cause = set(), {}

    @property
    def finished(self):
        return self.base == self.n or self.error is not None

    def start(self, now):
        """The first write."""
        return self._fresh(now)

    def deadline(self):
        """When silence about the oldest unanswered request sends the window again (PROTOCOL.md "Timeout"): a quarter
        of the timeout, doubled by each silence since it became the oldest, after its latest copy's answer is due on
        the line model or after it became the oldest (a held request's answer follows the filler's), whichever is
        later, and never after the timeout; the slow types wait their own time."""
        i = self.base
        if self.types[i] in SLOW_TYPES:
            return self.sent_at[i] + max(self.timeout, SLOW_TIMEOUT)
        late = self.sent_at[i] + self.timeout
        if not self.byte_time or self.fixed_timeout:
            return late
        return min(late, max(self.due[i], self.oldest_since) + self.timeout / 4 * 2 ** self.silences)

    def feed(self, ev):
        """A frame (or a Reject) received: marks what it shows lost."""
        if self.error is not None:
            return
        if isinstance(ev, frame.Reject):
            self.counters.rejects += 1
            return
        copy = self._probe_answered(ev)
        if copy is not None:
            self._on_probe(copy)
            return
        k = (ev.seq - self.seqs[self.base]) & 0xFF
        if k >= self.nxt - self.base:
            return  # not in flight: a late copy of an earlier answer
        i = self.base + k
        if ev.type not in (MsgType.NAK, self.types[i] | RESPONSE_BIT) or self.results[i] is not None:
            return  # stale: another type with this SEQ, or about a request already answered
        if ev.type == MsgType.NAK:
            self._on_nak(i, ev)
        else:
            self._on_answer(i, ev)

    def step(self, now):
        """After the frames received: the oldest answered ones leave the window, the requests shown lost (or, on a
        silence past the deadline, every unanswered one) are sent again, and new ones go out if there is room."""
        if self.error is not None:
            return []
        if self.results[self.base] is not None:
            while self.base < self.nxt and self.results[self.base] is not None:
                self.base += 1
            self.tries = self.silences = 0
            self.oldest_since = now
            if self.base == self.nxt:
                self.seen = self.tx  # every request written is answered: what was left on the line no longer counts
        if self.base == self.n:
            return []
        writes = []
        again = self._resends(now)
        self.again, cause = set(), self.cause
        self.cause = {}
        if again:
            if again[0] == self.base:
                self.tries += 1
                if self.tries > self.retries:
                    self.error = (f"{self.types[self.base].name} seq {self.seqs[self.base]}: no response after "
                                  f"{self.retries} retransmissions")
                    return []
            self.counters.retransmissions += len(again)
            for i in again:
                why = cause.pop(i, "?")
                self.counters.causes[why] = self.counters.causes.get(why, 0) + 1
            writes.append(self._send(again, True, now))
        return writes + self._fresh(now)

    def _resends(self, now):
        again = sorted(j for j in self.again if self.results[j] is None)
        if not again and self.base < self.nxt and now >= self.deadline():
            again = [i for i in range(self.base, self.nxt) if self.results[i] is None]  # silence: from the oldest
            self.counters.timeouts += 1 if again else 0
            self.silences += 1
            self.last_timeout_tx = self.tx
            for i in again:
                self.cause.setdefault(i, "timeout_probe_lost" if self.probes else "timeout_no_probe")
        return again

    def _fresh(self, now):
        """New requests go out as answers come back (PROTOCOL.md "Pacing"): a resend then waits behind a few frames,
        not behind the whole window, and is answered before the window runs dry."""
        room = min(self.n, self.base + self.win) - self.nxt
        if self.win > 1 and self.ahead:
            room = min(room, self.ahead - (self.tx - self.seen))
        if self.nxt >= self.n or room <= 0:
            return []
        fresh = list(range(self.nxt, self.nxt + room))
        self.nxt = fresh[-1] + 1
        return [self._send(fresh, False, now)]

    def _model(self, nbytes, back):
        """The line model (PROTOCOL.md "Timeout"): a frame written now arrives after the bytes written before it, and
        its answer goes back after it arrived and after the answers before it; returns when that answer is out."""
        self.line[0] += nbytes * self.byte_time
        self.line[1] = max(self.line[1], self.line[0]) + back * self.byte_time
        return self.line[1]

    def _send(self, which, resent, now):
        self.line[0] = max(self.line[0], now)
        for i in which:
            self.tx += 1
            self.txs[i].append(self.tx)
            self.sent_at[i] = now
            self.due[i] = self._model(self.sizes[i], self.answer[i])
            if i in self.by_release:
                self.release_copy[i] = self.tx
        self.by_release.clear()
        probe = None
        # Nothing goes out after this write until answers come: a probe behind it shows what it lost.
        if self.probe and self.win > 1 and (resent or self.nxt == self.n) and \
                (self.nxt == self.n or self.nxt - self.base >= self.win):
            self.tx += 1
            probe = (self.seqs[self.base] - 1) & 0xFF  # never in flight: answered before the oldest unanswered one
            self.probes.append((probe, self.tx))
            self._model(frame.OVERHEAD, frame.OVERHEAD + 1)
            self.counters.probes += 1
        return Write(which, probe)

    def _mark(self, i, why):
        self.again.add(i)
        self.cause.setdefault(i, why)

    def _probe_answered(self, ev):
        """The copy number of the probe a NAK UNKNOWN_TYPE answers (the oldest written with its SEQ: the earliest it
        can be about; older probes still waiting were lost), else None."""
        if ev.type != MsgType.NAK or ev.payload != messages.pack_nak(Status.UNKNOWN_TYPE):
            return None
        for k, (seq, copy) in enumerate(self.probes):
            if seq == ev.seq:
                del self.probes[:k + 1]
                return copy
        return None

    def _on_probe(self, copy):
        self.seen = max(self.seen, copy)
        self.counters.probes_answered += 1
        if copy < self.last_timeout_tx:
            self.counters.needless_timeouts += 1  # the answers were on their way: the line model was early
        # Every unanswered request not held whose latest copy went out before the probe lost it.
        for j in range(self.base, self.nxt):
            if self.results[j] is None and not self.held[j] and self.txs[j][-1] < copy:
                self._mark(j, "probe")

    def _counted_copy(self, i):
        """Counts an event naming request i: the earliest copy it can be about."""
        self.events[i] += 1
        return self.txs[i][min(self.events[i], len(self.txs[i])) - 1]

    def _on_nak(self, i, ev):
        reason = messages.unpack_nak(ev.payload)["reason"] if len(ev.payload) == 1 else None
        if reason not in (Status.HELD, Status.SEQ_GAP, Status.UNKNOWN_TYPE, Status.SEQ_OLD):
            # BAD_CRC, BAD_LENGTH: its SEQ was read from damaged bytes and may name another request, so it is not
            # counted; naming the oldest unanswered one it sends that again (at worst a copy answered from memory).
            if i == next(j for j in range(self.base, self.nxt) if self.results[j] is None):
                self._mark(i, "bad_crc_nak")
            return
        copy = self._counted_copy(i)
        self.seen = max(self.seen, copy)
        if reason == Status.SEQ_OLD:
            self.error = f"{self.types[i].name} seq {ev.seq}: NAK {Status(reason).name}"
            return
        self.held[i] = reason == Status.HELD  # a SEQ_GAP after HELD: the firmware dropped it (ESTOP)
        if self.held[i]:
            self.again.discard(i)
        elif copy == self.txs[i][-1]:
            self._mark(i, "refused")  # its latest copy was refused
        self._lost_before(i, copy, "nak_" + Status(reason).name.lower())

    def _on_answer(self, i, ev):
        try:
            self.results[i] = messages.unpack_response(self.types[i], ev.payload)
        except ValueError as e:
            self.error = f"malformed response {ev.type:#04x} seq {ev.seq}: {e}"
            return
        self.again.discard(i)
        copy = self._counted_copy(i)
        # The firmware runs requests in SEQ order: every unanswered request before this one ran, and its answer (sent
        # before this one) was lost. A held request's answer follows the answer of the request that filled the gap,
        # not its own copy: it tells this, and nothing by copies.
        for j in range(self.base, i):
            # Not again for the other answers of the same release (they show nothing newer).
            if self.results[j] is None and (self.held[j] or self.held[i]) and \
                    (self.held[j] or self.release_copy[j] != self.txs[j][-1]):
                self.held[j] = False
                self._mark(j, "release")
                self.by_release.add(j)
        if self.held[i]:
            return
        self.seen = max(self.seen, copy)
        self._lost_before(i, copy, "answer")

    def _lost_before(self, i, copy, why):
        """Answers come in frame order: an unanswered request, not held, whose latest copy went out before this copy
        lost it (the frame, or its answer)."""
        for j in range(self.base, self.nxt):
            if j != i and self.results[j] is None and not self.held[j] and self.txs[j][-1] < copy:
                self._mark(j, why)
