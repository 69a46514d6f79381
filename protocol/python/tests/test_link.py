"""test_link.py - Link (pyserial) against a firmware-like peer on a pty: retransmission, NAK, duplicates, LinkError,
and streams with a window in flight (go-back-N over drops, lost answers and corrupt bytes)."""
import os
import random
import select
import threading
import time
import tty

import pytest
import serial  # pyserial (tools/apt-packages.txt): missing is a failure, never a skip
import serial.serialutil

from rbx1proto import frame, messages  # noqa: E402
from rbx1proto.link import Link, LinkError  # noqa: E402
from rbx1proto import link as link_module  # noqa: E402
from rbx1proto.messages import MsgType, Status  # noqa: E402
from rbx1proto.window import Window  # noqa: E402

# The peer is a thread of this process: on a loaded test machine it can be descheduled for tens of milliseconds,
# and a shorter timeout then counts retransmissions that no lost frame caused.
TIMEOUT = 0.25


class Peer(threading.Thread):
    """A firmware stand-in written with the Python protocol: the receiver's window (order, requests ahead of a gap
    held, at-most-once execution with remembered answers), and knobs to drop requests, NAK them, lose or delay responses, add line noise, or
    corrupt received bytes."""

    def __init__(self, master):
        super().__init__(daemon=True)
        self.master = master
        self.decoder = frame.Decoder()
        self.stop = threading.Event()
        self.lock = threading.Lock()
        self.received = []      # wire bytes of every valid frame received
        self.executed = []      # types executed (duplicates excluded)
        self.duplicates = 0
        self.window = Window()
        self.moves = []         # MOVE targets[0] in the order executed
        self.refused = []       # (seq, reason) of NAKs for gaps and old frames
        self.held = []          # SEQs answered NAK HELD (copies of a held request included)
        self.corrupt = 0.0      # probability of flipping each received byte
        self.rng = random.Random(7)
        self.drop = 0           # ignore the next N requests entirely (frames of a request type: not the link's probes)
        self.drop_seq = {}      # SEQ -> how many more frames with that SEQ to ignore entirely
        self.drop_probes = 0    # ignore the next N frames of no request type (the link's probes)
        self.times = []         # when each frame of `received` was read (time.monotonic())
        self.probes = 0         # frames of no request type NAKed UNKNOWN_TYPE (the link's probes)
        self.nak = 0            # answer the next N requests with a NAK instead
        self.nak_reason = Status.BAD_CRC  # the reason those NAKs give
        self.lose = 0           # execute the next N requests but lose their responses
        self.delay = 0.0        # seconds before each response
        self.hold_until_copy = False  # keep the next new request's response until its retransmission arrives
        self.held_response = None
        self.noise = b""        # bytes sent before each response
        self.nak_other_seq = False
        self.nak_next_seq = False
        self.silent = False

    def run(self):
        while not self.stop.is_set():
            r, _, _ = select.select([self.master], [], [], 0.01)
            if not r:
                continue
            try:
                data = os.read(self.master, 512)
            except OSError:
                return
            if self.corrupt:
                data = bytes(b ^ 0x10 if self.rng.random() < self.corrupt else b for b in data)
            with self.lock:
                for ev in self.decoder.feed(data):
                    if isinstance(ev, frame.Frame):
                        self.handle(ev)

    def send(self, data):
        os.write(self.master, data)

    def handle(self, f):
        self.received.append(frame.encode(f.seq, f.type, f.payload))
        self.times.append(time.monotonic())
        if self.silent:
            return
        if self.drop_probes and messages.request_len(f.type) < 0:
            self.drop_probes -= 1
            return
        if self.drop and messages.request_len(f.type) >= 0:
            self.drop -= 1
            return
        if self.drop_seq.get(f.seq, 0) and messages.request_len(f.type) >= 0:
            self.drop_seq[f.seq] -= 1
            return
        if self.nak:
            self.nak -= 1
            self.send(frame.encode(f.seq, MsgType.NAK, messages.pack_nak(self.nak_reason)))
            return
        verdict, cached, last = self.window.accept(f)
        if verdict == "unknown":
            self.probes += 1
            self.send(frame.encode(f.seq, MsgType.NAK, messages.pack_nak(Status.UNKNOWN_TYPE)))
            return
        if verdict == "held":
            self.held.append(f.seq)
            self.send(frame.encode(f.seq, MsgType.NAK, messages.pack_nak(Status.HELD)))
            return
        if verdict == "duplicate":
            self.duplicates += 1  # a retransmission: answer again, do not execute again
            response = cached
        elif verdict in ("gap", "old"):
            reason = Status.SEQ_GAP if verdict == "gap" else Status.SEQ_OLD
            self.refused.append((f.seq, reason))
            self.send(frame.encode(f.seq, MsgType.NAK, messages.pack_nak(reason)))
            return
        else:
            response = frame.encode(f.seq, f.type | 0x80, self.execute(f, last))
            if verdict == "new":
                self.window.record(f.seq, f.crc, response)
        if self.lose:
            self.lose -= 1  # the response is lost (the held requests it releases still run and answer)
        elif self.hold_until_copy and verdict == "new":
            self.hold_until_copy = False
            self.held_response = response  # late: it goes out just before the copy's answer
        else:
            if self.held_response:
                self.send(self.held_response)
                self.held_response = None
            if self.delay:
                time.sleep(self.delay)
            if self.nak_other_seq:
                self.send(frame.encode((f.seq + 100) & 0xFF, MsgType.NAK, messages.pack_nak(Status.BAD_CRC)))
            if self.nak_next_seq:  # a BAD_CRC NAK whose SEQ byte was damaged into the next request's
                self.send(frame.encode((f.seq + 1) & 0xFF, MsgType.NAK, messages.pack_nak(Status.BAD_CRC)))
            self.send(self.noise + response)
        if verdict == "bypass":  # ESTOP: the held requests are dropped, never run, each NAKed SEQ_GAP
            for seq in self.window.drop_held():
                self.send(frame.encode(seq, MsgType.NAK, messages.pack_nak(Status.SEQ_GAP)))
        while verdict == "new" and (h := self.window.release()) is not None:  # a filled gap: the held ones run
            response = frame.encode(h.seq, h.type | 0x80, self.execute(h, None))
            self.window.record(h.seq, h.crc, response)
            self.send(response)

    def execute(self, f, last_seq):
        t = MsgType(f.type)
        self.executed.append(t)
        fields = {name: ([0] * count if count else 0) for name, _, count in messages.RESPONSE_FIELDS[t]}
        if t == MsgType.HELLO:
            fields.update(proto_version=messages.PROTO_VERSION, joints=6, queue_size=16, last_seq=last_seq, window=8)
        if t == MsgType.STATUS:
            fields.update(moves_done=self.executed.count(MsgType.MOVE), gripper_us=1000 + f.seq)  # tells SEQs apart
        if t == MsgType.MOVE:
            fields.update(queue_free=15)
            self.moves.append(messages.unpack_request(t, f.payload)["target"][0])
        return messages.pack_response(t, **fields)


@pytest.fixture
def pty_pair():
    master, slave = os.openpty()
    tty.setraw(slave)
    peer = Peer(master)
    peer.start()
    link = Link(os.ttyname(slave), timeout=TIMEOUT, retries=5)
    yield link, peer
    link.close()
    peer.stop.set()
    peer.join(1)
    os.close(slave)
    os.close(master)


MOVE = dict(target=[100, -200, 300, 0, 5, -6], duration_ms=250)


def test_request_response(pty_pair):
    link, peer = pty_pair
    link.timeout = 30.0  # nothing is lost here: only a peer thread the load held up 0.25 s made a retransmission
    r = link.request(MsgType.MOVE, **MOVE)
    assert r == {"status": 0, "queue_free": 15}
    s = link.request(MsgType.STATUS)
    assert s["moves_done"] == 1 and s["position"] == [0] * 6
    assert link.seq == 2 and link.retransmissions == 0
    assert [frame.Decoder().feed(w)[0].seq for w in peer.received] == [0, 1]


def test_retransmits_same_bytes_on_timeout(pty_pair):
    link, peer = pty_pair
    peer.drop = 2
    t0 = time.monotonic()
    assert link.request(MsgType.MOVE, **MOVE)["status"] == Status.OK
    assert time.monotonic() - t0 >= 2 * TIMEOUT
    assert link.retransmissions == 2
    assert len(peer.received) == 3 and len(set(peer.received)) == 1  # byte-identical retransmissions
    assert peer.executed == [MsgType.MOVE]


def test_retransmits_at_once_on_nak(pty_pair):
    link, peer = pty_pair
    peer.nak = 1
    link.timeout = 30.0  # a timeout waited would show as 30 s, which no load comes near (1 s sat next to 0.5 s)
    t0 = time.monotonic()
    assert link.request(MsgType.HEARTBEAT) == {"status": 0}
    assert time.monotonic() - t0 < 30.0  # no waiting for the timeout
    assert link.retransmissions == 1
    assert len(peer.received) == 2 and peer.received[0] == peer.received[1]


def test_nak_of_another_seq_and_noise_are_ignored(pty_pair):
    link, peer = pty_pair
    peer.nak_other_seq = True
    peer.noise = b"\x00\xa5\x3b\x07\x13" + b"\xa5\x00\x01\x02\xde\xad"  # a bad-length and a bad-CRC candidate
    link.timeout = 30.0  # the retransmission counted below can come only from the NAK or the noise, not the load
    assert link.request(MsgType.STATUS)["status"] == Status.OK
    assert link.retransmissions == 0
    assert link.rejects >= 2


def test_lost_response_duplicate_is_answered_not_reexecuted(pty_pair):
    link, peer = pty_pair
    peer.lose = 1
    assert link.request(MsgType.MOVE, **MOVE) == {"status": 0, "queue_free": 15}
    assert link.retransmissions == 1
    assert peer.executed == [MsgType.MOVE] and peer.duplicates == 1
    assert link.request(MsgType.STATUS)["moves_done"] == 1


def test_late_response_then_stale_duplicate_is_ignored(pty_pair):
    link, peer = pty_pair
    link.timeout = 0.1
    peer.hold_until_copy = True  # the first answer comes after the retransmission, whatever the load
    assert link.request(MsgType.STATUS)["gripper_us"] == 1000
    # The second (cached) response to SEQ 0 is still coming; the next STATUS (SEQ 1) must not take it for its own.
    assert link.request(MsgType.STATUS)["gripper_us"] == 1001
    assert link.retransmissions >= 1  # the delayed peer may make the second request wait too
    assert peer.executed == [MsgType.STATUS, MsgType.STATUS] and peer.duplicates >= 1


def test_link_error_after_retries(pty_pair):
    link, peer = pty_pair
    peer.silent = True
    t0 = time.monotonic()
    with pytest.raises(LinkError):
        link.request(MsgType.HEARTBEAT)
    elapsed = time.monotonic() - t0
    assert link.retransmissions == 5
    time.sleep(0.05)
    assert len(peer.received) == 6 and len(set(peer.received)) == 1
    assert elapsed >= 6 * TIMEOUT * 0.9  # it waited out every timeout (no upper bound: a loaded machine adds to it)
    assert link.seq == 1  # the SEQ is consumed: the next request is a new one


def test_hello_starts_a_session_and_reports_the_window(pty_pair):
    link, peer = pty_pair
    link.seq = 41
    link.request(MsgType.HEARTBEAT)  # the firmware's last request of an earlier session: SEQ 41
    link.seq = 200
    r = link.hello()
    assert r["last_seq"] == 41 and r["proto_version"] == messages.PROTO_VERSION and r["window"] == 8
    assert link.seq == 201 and link.window == 8
    link.request(MsgType.STATUS)
    assert frame.Decoder().feed(peer.received[-1])[0].seq == 201
    assert peer.refused == []


def test_seq_wraps(pty_pair):
    link, peer = pty_pair
    link.seq = 255
    link.request(MsgType.HEARTBEAT)
    link.request(MsgType.HEARTBEAT)
    assert [frame.Decoder().feed(w)[0].seq for w in peer.received] == [255, 0]
    assert peer.duplicates == 0 and peer.executed == [MsgType.HEARTBEAT] * 2


def test_send_raw_garbage_then_request(pty_pair):
    link, peer = pty_pair
    link.send_raw(b"\xa5\x05\x00\x01\x02")  # an unfinished frame at the peer...
    time.sleep(0.02)
    with peer.lock:
        assert peer.decoder.reset()  # ...which the firmware drops after its inter-byte timeout
    assert link.request(MsgType.STATUS)["status"] == Status.OK


def test_config_reset_waits_longer(pty_pair):
    link, peer = pty_pair
    peer.delay = 0.4  # EEPROM writes: slower than the link's timeout, within the 1 s of CONFIG_*
    assert link.request(MsgType.CONFIG_RESET) == {"status": 0}
    assert link.retransmissions == 0


def test_late_wakeup_reads_waiting_response_without_retransmitting(pty_pair):
    # The process is descheduled right after sending: the peer answers meanwhile, and every time the Link looks at
    # its clock while that response sits unread, 10 s have passed (far beyond the link's timeout). The response
    # already waiting must be taken, with no retransmission.
    link, peer = pty_pair
    offset = [0.0]

    def clock():
        if link.ser.in_waiting:
            offset[0] += 10.0
        return time.monotonic() + offset[0]

    write = link.write

    def write_then_sleep(data):
        write(data)
        end = time.monotonic() + 2.0
        while link.ser.in_waiting == 0 and time.monotonic() < end:
            time.sleep(0.005)  # "descheduled" until the response has arrived

    link.clock = clock
    link.write = write_then_sleep
    r = link.request(MsgType.MOVE, **MOVE)
    assert r == {"status": 0, "queue_free": 15}
    s = link.request(MsgType.STATUS)
    assert s["moves_done"] == 1 and s["gripper_us"] == 1001  # the STATUS's own answer (SEQ 1), not a stale one
    assert offset[0] >= 20.0  # the clock did jump past the deadline before each read
    assert link.retransmissions == 0
    time.sleep(0.05)
    assert len(peer.received) == 2 and peer.duplicates == 0


def stream_moves(link, n, start=0):
    return link.stream([(MsgType.MOVE, dict(target=[start + i, 0, 0, 0, 0, 0], duration_ms=0)) for i in range(n)])


def test_descheduled_during_a_write_is_no_error(pty_pair, monkeypatch):
    # Every look at the wall clock finds 10 s gone, as when a loaded machine deschedules the process mid-write:
    # pyserial's own write_timeout (1 s, measured from the call) raised SerialTimeoutException with every byte
    # written (e2e_avrsim's first HELLO at load 18). The Link counts only a port that takes nothing.
    link, peer = pty_pair
    jump = [time.monotonic()]

    def late():
        jump[0] += 10.0
        return jump[0]

    monkeypatch.setattr(serial.serialutil.Timeout, "TIME", staticmethod(late))
    link.timeout = 30.0  # the Link's own clock is the real one: no retransmission however late the peer thread runs
    r = link.request(MsgType.MOVE, **MOVE)
    assert r == {"status": 0, "queue_free": 15}
    assert link.retransmissions == 0 and len(peer.received) == 1


def test_a_port_that_takes_nothing_fails_the_write():
    master, slave = os.openpty()
    tty.setraw(slave)
    link = Link(os.ttyname(slave), timeout=TIMEOUT, retries=5)
    try:
        t0 = time.monotonic()
        with pytest.raises(LinkError, match="the port took no byte for 1.0 s"):
            link.send_raw(b"\x00" * (1 << 20))  # nobody reads the master: the pty's buffer fills
        assert time.monotonic() - t0 >= 1.0
    finally:
        link.close()
        os.close(slave)
        os.close(master)


def test_stream_keeps_the_window_in_flight(pty_pair):
    link, peer = pty_pair
    link.timeout = 4.0  # no timeout in this test, however loaded the machine (0.25 s fired once at load 15)
    link.hello()
    rs = stream_moves(link, 40)
    assert [r["status"] for r in rs] == [Status.OK] * 40
    assert peer.moves == list(range(40)) and peer.duplicates == 0 and link.retransmissions == 0


def test_stream_window_capped_by_the_host(pty_pair):
    link, peer = pty_pair
    link.max_window = 3
    link.hello()
    assert link.window == 3
    stream_moves(link, 10)
    assert peer.moves == list(range(10))


def test_stream_resends_only_the_missing_one_after_a_dropped_request(pty_pair):
    link, peer = pty_pair
    link.ahead = 0  # the whole window written at once (no pacing): the 7 after the lost one are held
    link.hello()
    stream_moves(link, 5)
    peer.drop = 1  # the next request vanishes: the ones after it are held (NAK HELD) until it is sent again
    stream_moves(link, 20, start=5)
    assert peer.moves == list(range(25)), "executed out of order or twice"
    assert peer.held[:7] == [(link.seq - 19 + i) & 0xFF for i in range(7)] and not peer.refused
    assert link.retransmissions > 0


def test_stream_paced_keeps_the_resend_close_behind_the_lost_request(pty_pair):
    # With pacing (PROTOCOL.md "Pacing") no more than AHEAD frames are on the line beyond the latest copy an answer
    # or NAK was about: a lost request has at most AHEAD - 1 followers held before its resend goes out.
    link, peer = pty_pair
    link.timeout = 4.0  # no timeout in this test, however loaded the machine
    link.hello()
    assert link.ahead == link_module.AHEAD == 4
    peer.drop = 1
    rs = stream_moves(link, 20)
    assert [r["status"] for r in rs] == [Status.OK] * 20
    assert peer.moves == list(range(20)) and peer.duplicates == 0, "lost, repeated or reordered"
    assert len(peer.held) == link.ahead - 1 and not peer.refused
    assert link.retransmissions == 1 and link.timeouts == 0


def test_stream_lost_answers_are_answered_from_the_window(pty_pair):
    link, peer = pty_pair
    link.hello()
    peer.lose = 3  # the first three are executed but their answers are lost: sent again, answered from memory
    rs = stream_moves(link, 12)
    assert [r["status"] for r in rs] == [Status.OK] * 12
    assert peer.moves == list(range(12)) and peer.duplicates >= 3


def test_stream_under_corrupt_bytes_runs_everything_once_in_order(pty_pair):
    link, peer = pty_pair
    link.retries = 20
    link.hello()
    peer.corrupt = 0.01  # 1 % of the bytes the firmware receives, about one MOVE frame in four
    rs = stream_moves(link, 200)
    peer.corrupt = 0.0
    assert [r["status"] for r in rs] == [Status.OK] * 200
    assert peer.moves == list(range(200)), "lost, repeated or reordered"
    assert link.retransmissions > 0


def test_stream_nak_seq_old_is_an_error(pty_pair):
    link, peer = pty_pair
    link.hello()
    stream_moves(link, 3)
    link.seq = (link.seq - 20) & 0xFF  # a host that lost count: its SEQs are the past
    with pytest.raises(LinkError, match="SEQ_OLD"):
        stream_moves(link, 2, start=100)
    assert 100 not in peer.moves


def test_stream_nak_unknown_type_of_a_known_type_is_a_plain_nak(pty_pair):
    # PROTOCOL.md: an unknown type takes no place in the order, so a NAK UNKNOWN_TYPE for a request type the host
    # sent (a damaged or stale frame) means nothing ran: the stream goes back and every request runs once, in order.
    link, peer = pty_pair
    link.hello()
    peer.nak, peer.nak_reason = 2, Status.UNKNOWN_TYPE
    rs = stream_moves(link, 10)
    assert [r["status"] for r in rs] == [Status.OK] * 10
    assert peer.moves == list(range(10)) and link.retransmissions > 0


def test_unknown_type_takes_no_seq(pty_pair):
    # A frame of an unknown type is NAKed UNKNOWN_TYPE and its SEQ stays the next in order: a request with that SEQ
    # runs (not a duplicate, not SEQ_OLD), and the HELLO after it reports that request as the last one answered.
    link, peer = pty_pair
    link.timeout = 4.0  # no timeout in this test, however loaded the machine (a stream: 1 s past due)
    link.hello()
    seq = link.seq
    link.send_raw(frame.encode(seq, 0x33, b""))
    link.ser.timeout = 2.0
    nak = frame.encode(seq, MsgType.NAK, messages.pack_nak(Status.UNKNOWN_TYPE))
    assert link.ser.read(len(nak)) == nak
    r = link.request(MsgType.MOVE, **MOVE)
    assert r["status"] == Status.OK and peer.moves == [100] and link.retransmissions == 0
    assert link.hello()["last_seq"] == seq


def test_stream_resends_only_what_the_answers_show_lost(pty_pair):
    # Answers and NAKs come back in the order of the copies written: a lost answer costs one resend of its request,
    # a lost request one resend of it alone (its followers are held: NAK HELD), nothing more (a timeout resends all).
    link, peer = pty_pair
    link.timeout = 4.0  # no timeout in this test, however loaded the machine (a stream: 1 s past due)
    link.hello()
    peer.lose = 1  # the first answer is lost
    stream_moves(link, 12)
    assert peer.moves == list(range(12)) and link.retransmissions == 1
    peer.drop = 1  # the next stream's first frame vanishes: its 7 followers in the window are held
    link.ahead = 0  # (the whole window written at once, no pacing)
    rs = stream_moves(link, 12, start=12)
    assert [r["status"] for r in rs] == [Status.OK] * 12
    assert peer.moves == list(range(24)) and len(peer.held) == 7 and not peer.refused
    assert link.retransmissions == 1 + 1, "only the missing request is sent again"


def test_stream_lost_filler_answer_is_sent_again_once(pty_pair):
    # The first frame vanishes and its 7 followers are held; its resend fills the gap but its answer is lost. The
    # held ones' answers (each written on its own) show it ran: it is sent again once, answered from memory, with
    # no timeout, however the answers are split between reads.
    link, peer = pty_pair
    link.timeout = 4.0  # no timeout in this test, however loaded the machine (a stream: 1 s past due)
    link.hello()
    peer.drop, peer.lose = 1, 1
    rs = stream_moves(link, 10)
    assert [r["status"] for r in rs] == [Status.OK] * 10
    assert peer.moves == list(range(10)) and peer.duplicates == 1
    assert link.retransmissions <= 2 and link.timeouts == 0  # the lost request, its lost answer: once each


def test_stream_lost_resend_is_sent_again_after_the_probe_not_the_timeout(pty_pair):
    # The first request vanishes and so does its first resend (written when its followers came back held): the
    # probe written behind that resend is answered after it, which shows it lost; it goes again at once. Today's
    # rule without the probe waited for the timeout (1 s past due here: the count of timeouts tells).
    link, peer = pty_pair
    link.timeout = 4.0  # a stream's deadline: a quarter of it (1 s) after the answer is due
    link.ahead = 0  # the whole window at once: nothing new can follow the resend, only the probe
    link.hello()
    peer.drop_seq = {link.seq: 2}
    rs = stream_moves(link, 10)
    assert [r["status"] for r in rs] == [Status.OK] * 10
    assert peer.moves == list(range(10)) and peer.duplicates == 0, "lost, repeated or reordered"
    assert link.timeouts == 0 and link.retransmissions == 2  # the first request's two resends, nothing else
    assert link.probes >= 2  # behind each resend (and behind the stream's last request)


def test_stream_paced_goes_on_when_late_copies_answers_are_stale(pty_pair):
    # The first answer comes late, after the timeout's resend: the late answer is taken, and the resend's answer
    # (from memory) is stale. Nothing is in flight then, so what was left on the line must not hold back the rest:
    # before this rule the stream spun forever with every request written answered and no room to write more.
    link, peer = pty_pair
    link.timeout = 0.4
    link.ahead = 1
    link.hello()
    peer.hold_until_copy = True
    result = []
    t = threading.Thread(target=lambda: result.append(stream_moves(link, 5)), daemon=True)
    t.start()
    t.join(10)
    assert not t.is_alive(), "the stream stopped writing with nothing in flight"
    assert [r["status"] for r in result[0]] == [Status.OK] * 5
    assert peer.moves == list(range(5)) and link.timeouts == 1


def test_stream_paced_lost_resend_is_shown_by_the_requests_after_it(pty_pair):
    # Paced, new requests follow a resend: their NAKs (HELD) come after it, so a lost resend is sent again at once,
    # with neither a probe nor a timeout.
    link, peer = pty_pair
    link.timeout = 4.0
    link.hello()
    peer.drop_seq = {link.seq: 2}
    rs = stream_moves(link, 20)
    assert [r["status"] for r in rs] == [Status.OK] * 20
    assert peer.moves == list(range(20)) and peer.duplicates == 0, "lost, repeated or reordered"
    assert link.timeouts == 0 and link.retransmissions == 2
    assert link.probes == 1  # only behind the stream's last request


def test_stream_lost_last_request_is_sent_again_after_the_probe(pty_pair):
    # Nothing follows the stream's last request but the probe: its NAK shows the request lost, without a timeout.
    link, peer = pty_pair
    link.timeout = 4.0  # a stream's deadline: a quarter of it (1 s) after the answer is due
    link.hello()
    peer.drop_seq = {(link.seq + 9) & 0xFF: 1}
    rs = stream_moves(link, 10)
    assert [r["status"] for r in rs] == [Status.OK] * 10
    assert peer.moves == list(range(10)) and peer.duplicates == 0
    assert link.timeouts == 0 and link.retransmissions == 1


def test_stream_silence_times_out_on_the_line_model_before_the_timeout(pty_pair):
    # The stream's only request and the probe behind it vanish: nothing shows the loss but silence. The deadline is
    # the answer's due time on the line model plus a quarter of the timeout (PROTOCOL.md "Timeout"): the request
    # goes again about 1 s after the first copy, not after the 4 s of the timeout.
    link, peer = pty_pair
    link.timeout = 4.0
    link.hello()
    peer.drop_seq = {link.seq: 1}
    peer.drop_probes = 1
    rx0, resent0 = len(peer.received), link.retransmissions  # a loaded machine may have resent the HELLO
    rs = stream_moves(link, 1)
    assert [r["status"] for r in rs] == [Status.OK] and peer.moves == [0]
    assert link.timeouts == 1 and link.retransmissions - resent0 == 1
    assert len(peer.received) >= rx0 + 3 and peer.received[rx0 + 2] == peer.received[rx0]  # request, probe, again
    gap = peer.times[rx0 + 2] - peer.times[rx0]
    assert 0.5 <= gap < 3.0  # not before its deadline (1 s past due; the first copy may be read late), not at 4 s


def test_stream_stop_and_wait_writes_no_probe(pty_pair):
    link, peer = pty_pair
    link.max_window = 1
    link.hello()
    stream_moves(link, 5)
    assert peer.moves == list(range(5)) and link.probes == 0 and peer.probes == 0


def test_stream_held_then_estop_runs_nothing_held_and_resends(pty_pair):
    # The firmware drops held requests on ESTOP (NAK SEQ_GAP each): the stream sends them again and each runs
    # once, in order, after the missing one.
    link, peer = pty_pair
    link.timeout = 4.0  # no timeout in this test, however loaded the machine (a stream: 1 s past due)
    link.hello()
    peer.drop = 1
    orig = peer.handle

    def estop_after_held(f):  # an ESTOP arrives (another writer) right after the first request is held
        orig(f)
        if peer.held and not getattr(peer, "estopped", False):
            peer.estopped = True
            orig(frame.Decoder().feed(frame.encode(f.seq, MsgType.ESTOP, b""))[0])
    peer.handle = estop_after_held
    rs = stream_moves(link, 6)
    assert [r["status"] for r in rs] == [Status.OK] * 6
    assert peer.moves == list(range(6)), "a dropped held request ran, or ran twice"
    assert peer.executed.count(MsgType.ESTOP) == 1


def test_stream_bad_crc_naks_naming_other_requests_resend_nothing(pty_pair):
    # A BAD_CRC NAK's SEQ was read from damaged bytes: one naming a request still in flight (not the oldest) is
    # neither counted nor acted on (counted, it would make that request's later answers look like its latest
    # copy's and resend everything written before).
    link, peer = pty_pair
    link.timeout = 4.0  # no timeout in this test, however loaded the machine (a stream: 1 s past due)
    link.hello()
    peer.nak_next_seq = True
    rs = stream_moves(link, 30)
    assert [r["status"] for r in rs] == [Status.OK] * 30
    assert peer.moves == list(range(30)) and link.retransmissions == 0
