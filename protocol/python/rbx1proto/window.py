"""window.py - the receiver's window (PROTOCOL.md "Window"), as rbx1_window.c: SEQ order, requests ahead of a gap
held and run once it is filled (selective repeat), duplicates answered from memory over the last WINDOW requests,
further gaps and old frames refused. The vectors check both implementations."""
from .frame import Decoder
from .messages import MsgType, request_len

WINDOW = 8  # requests a host may keep in flight; the firmware remembers this many (HELLO reports it)
HELD_MAX = WINDOW - 1  # requests held ahead of a missing one: SEQ expect + 1 .. expect + WINDOW - 1

NEW, DUPLICATE, GAP, OLD, BYPASS, UNKNOWN, HELD = "new", "duplicate", "gap", "old", "bypass", "unknown", "held"


class Window:
    def __init__(self, size=WINDOW):
        self.size = size
        self.entries = []  # (seq, crc, answer), oldest first
        self.held = {}     # seq -> the frame held ahead of a gap, not run yet
        self.expect = 0
        self.synced = False

    def classify(self, seq, crc):
        """(verdict, remembered answer or None) for a request by its SEQ and CRC."""
        for s, c, answer in self.entries:
            if s == seq and c == crc:
                return DUPLICATE, answer
        if not self.synced or seq == self.expect:
            return NEW, None
        if seq in self.held:
            return (HELD if self.held[seq].crc == crc else OLD), None  # other bytes at a held SEQ: a used SEQ
        ahead = (seq - self.expect) & 0xFF
        if ahead < self.size:
            return HELD, None
        return (GAP if ahead < 128 else OLD), None

    def accept(self, frame):
        """(verdict, answer, last_seq): ESTOP bypasses (the caller then drops the held requests); a TYPE of no request
        (unknown ids, NAK, responses) is UNKNOWN whatever its SEQ (NAK UNKNOWN_TYPE, no place in the order); a HELLO
        that is not a duplicate starts a new session (last_seq is then the SEQ answered before it, else None); a
        request 1..size-1 ahead of the next expected SEQ is held (HELD; a copy of a held one is HELD again); anything
        else is classified."""
        if frame.type == MsgType.ESTOP:
            return BYPASS, None, None
        if request_len(frame.type) < 0:
            return UNKNOWN, None, None
        verdict, answer = self.classify(frame.seq, frame.crc)
        # A HELLO is a retransmission only while it is the newest request remembered; once others followed it, the
        # same bytes are a new host's session starting at the same SEQ (answering from memory would acknowledge
        # requests never executed).
        if frame.type == MsgType.HELLO and (verdict != DUPLICATE or (frame.seq, frame.crc) != self.entries[-1][:2]):
            last = self.last_seq()
            self.restart()
            return NEW, None, last
        if verdict == HELD:
            self.held.setdefault(frame.seq, frame)
        return verdict, answer, None

    def release(self):
        """After a request in order was run and recorded: the held frame now next in order (taken out), or None. The
        caller runs and records it, and asks again until None."""
        return self.held.pop(self.expect, None) if self.synced else None

    def drop_held(self):
        """ESTOP: forgets every held frame, none run; their SEQs in SEQ order (each is NAKed SEQ_GAP)."""
        seqs = sorted(self.held, key=lambda s: (s - self.expect) & 0xFF)
        self.held = {}
        return seqs

    def record(self, seq, crc, answer):
        self.entries = (self.entries + [(seq, crc, answer)])[-self.size:]
        self.expect = (seq + 1) & 0xFF
        self.synced = True

    def restart(self):
        self.entries = []
        self.held = {}
        self.synced = False

    def last_seq(self):
        return self.entries[-1][0] if self.entries else 0xFF


def replay(window, steps):
    """Feeds each step's wire frame (hex, "wire") to window as a receiver does, in order; yields per step
    (verdict, answer, last_seq, released, dropped): a new request is recorded with its step index as its answer, then
    the held frames it lets through are released and recorded in order (released: the step index each was first held
    at); a bypass (ESTOP) drops the held frames (dropped: their SEQs). The vectors' generator and tests share it."""
    first_held = {}
    for i, st in enumerate(steps):
        (f,) = Decoder().feed(bytes.fromhex(st["wire"]))
        verdict, answer, last = window.accept(f)
        if verdict == HELD:
            first_held.setdefault(f.seq, i)
        released, dropped = [], []
        if verdict == NEW:
            window.record(f.seq, f.crc, i)
            while (h := window.release()) is not None:
                released.append(first_held.pop(h.seq))
                window.record(h.seq, h.crc, released[-1])
        if verdict == BYPASS:
            dropped = window.drop_held()
            for s in dropped:
                first_held.pop(s)
        yield verdict, answer, last, released, dropped
