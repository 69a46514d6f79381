"""window.py - the receiver's window (PROTOCOL.md "Window"), as rbx1_window.c: SEQ order, duplicates answered from
memory over the last WINDOW requests, gaps and old frames refused. The vectors check both implementations."""
from .messages import MsgType, request_len

WINDOW = 8  # requests a host may keep in flight; the firmware remembers this many (HELLO reports it)

NEW, DUPLICATE, GAP, OLD, BYPASS, UNKNOWN = "new", "duplicate", "gap", "old", "bypass", "unknown"


class Window:
    def __init__(self, size=WINDOW):
        self.size = size
        self.entries = []  # (seq, crc, answer), oldest first
        self.expect = 0
        self.synced = False

    def classify(self, seq, crc):
        """(verdict, remembered answer or None) for a request by its SEQ and CRC."""
        for s, c, answer in self.entries:
            if s == seq and c == crc:
                return DUPLICATE, answer
        if not self.synced or seq == self.expect:
            return NEW, None
        return (GAP if (seq - self.expect) & 0xFF < 128 else OLD), None

    def accept(self, frame):
        """(verdict, answer, last_seq): ESTOP bypasses; a TYPE of no request (unknown ids, NAK, responses) is UNKNOWN
        whatever its SEQ (NAK UNKNOWN_TYPE, no place in the order); a HELLO that is not a duplicate starts a new session (last_seq
        is then the SEQ answered before it, else None); anything else is classified."""
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
        return verdict, answer, None

    def record(self, seq, crc, answer):
        self.entries = (self.entries + [(seq, crc, answer)])[-self.size:]
        self.expect = (seq + 1) & 0xFF
        self.synced = True

    def restart(self):
        self.entries = []
        self.synced = False

    def last_seq(self):
        return self.entries[-1][0] if self.entries else 0xFF
