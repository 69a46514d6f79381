#!/usr/bin/python3
"""make_sender_traces.py - writes sender_traces.json: event traces of the window sender (Link.stream in Python,
Link::stream in C++) that both implementations must reproduce exactly.

Each scenario runs the Python sender (rbx1proto/sender.py) against a model firmware (the receiver's window of
window.py: requests in SEQ order, held ahead of a gap, answered from memory, probes NAKed UNKNOWN_TYPE) over a line
that loses, damages or duplicates chosen frames. The trace records, step by step, the time, the frames the sender was
told of and what it wrote then; the tests of both implementations feed the same frames at the same times and must
write the same. Run after a change to the sender: /usr/bin/python3 protocol/vectors/make_sender_traces.py
"""
import json
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
from rbx1proto import frame, messages  # noqa: E402
from rbx1proto.messages import MsgType, Status  # noqa: E402
from rbx1proto.sender import Sender  # noqa: E402
from rbx1proto.window import Window  # noqa: E402

LATENCY_US = 2000    # from a write to the first of its replies
SPACING_US = 300     # between replies delivered one by one
SILENCE_US = 5       # a silence is fed this long after the sender's deadline (the two clocks round differently)


def request_frame(i, seq, msg_type):
    """The wire bytes of request i: distinct payloads, so that the firmware tells copies from new requests."""
    if msg_type == MsgType.MOVE:
        payload = messages.pack_request(msg_type, target=[i, -i, 0, 0, 0, 0], duration_ms=100 + i)
    elif msg_type == MsgType.CONFIG_SET:
        payload = messages.pack_request(msg_type, joint=0, key=0, value=i)
    else:
        payload = messages.pack_request(msg_type)
    return frame.encode(seq, msg_type, payload)


def event_frame(ev):
    """A trace event as the frame the sender receives: ["R", seq, type] a response (status OK, zeros), ["N", seq,
    reason] a NAK. The tests build the same."""
    if ev[0] == "R":
        return frame.encode(ev[1], ev[2] | 0x80, bytes(messages.response_len(MsgType(ev[2]))))
    return frame.encode(ev[1], MsgType.NAK, messages.pack_nak(Status[ev[2]]))


def decode(wire):
    (f,) = frame.Decoder().feed(wire)
    return f


class Firmware:
    """The receiver side: what it answers to each frame that reaches it."""

    def __init__(self, first_seq):
        self.window = Window()
        self.window.record((first_seq - 1) & 0xFF, 0, None)  # the session's HELLO: the stream's SEQs follow it

    def handle(self, wire, damaged):
        f = decode(wire)
        if damaged:  # its CRC failed: NAK BAD_CRC with the SEQ as read (here undamaged)
            return [["N", f.seq, "BAD_CRC"]]
        verdict, answer, _ = self.window.accept(f)
        if verdict == "unknown":
            return [["N", f.seq, "UNKNOWN_TYPE"]]
        if verdict == "held":
            return [["N", f.seq, "HELD"]]
        if verdict in ("gap", "old"):
            return [["N", f.seq, "SEQ_GAP" if verdict == "gap" else "SEQ_OLD"]]
        if verdict == "duplicate":
            return [["R", f.seq, answer]]
        out = [["R", f.seq, f.type]]
        self.window.record(f.seq, f.crc, f.type)
        while (h := self.window.release()) is not None:
            self.window.record(h.seq, h.crc, h.type)
            out.append(["R", h.seq, h.type])
        return out


def run(name, description, n=12, types=None, window=8, ahead=4, timeout_ms=100, baud=115200, retries=5,
        first_seq=0x20, lose_to=(), damage_to=(), lose_back=(), duplicate_back=(), dead_from=None, extra=None,
        one_by_one=True):
    """lose_to / damage_to: copy numbers (1-based, every frame written, probes included) lost or damaged on the way
    to the firmware; lose_back / duplicate_back: reply numbers (1-based) lost or delivered twice; dead_from: the copy
    number from which the line carries nothing; extra: {copy number: [event, ...]} replies added after that copy's
    (stale or refused frames); one_by_one: each reply a step of its own, else each write's replies in one step."""
    types = [MsgType(t) for t in (types or [MsgType.MOVE] * n)]
    n = len(types)
    seqs = [(first_seq + i) & 0xFF for i in range(n)]
    wires = [request_frame(i, seqs[i], t) for i, t in enumerate(types)]
    s = Sender(types, seqs, [len(w) for w in wires], window, ahead=ahead, timeout=timeout_ms / 1000, baudrate=baud,
               retries=retries)
    fw = Firmware(first_seq)
    copies = replies = 0
    pending = []  # [at_us, [events]] in arrival order
    steps = []

    def deliver(now, writes):
        nonlocal copies, replies
        out = []
        for w in writes:
            frames = [wires[i] for i in w.frames]
            if w.probe is not None:
                frames.append(frame.encode(w.probe, MsgType.NAK, b""))
            for wire in frames:
                copies += 1
                if copies in lose_to or (dead_from is not None and copies >= dead_from):
                    continue
                for ev in fw.handle(wire, copies in damage_to) + (extra or {}).get(copies, []):
                    replies += 1
                    if replies not in lose_back:
                        out += [ev] * (2 if replies in duplicate_back else 1)
        at = max([now + LATENCY_US] + [p[0] + SPACING_US for p in pending[-1:]])
        if one_by_one:
            for k, ev in enumerate(out):
                pending.append([at + k * SPACING_US, [ev]])
        elif out:
            pending.append([at, out])

    now = 0
    writes = s.start(now / 1e6)
    steps.append({"at_us": now, "in": [], "out": [[w.frames, w.probe] for w in writes]})
    deliver(now, writes)
    while not s.finished:
        deadline_us = s.deadline() * 1e6
        if pending and pending[0][0] < deadline_us:
            at, events = pending.pop(0)
            assert deadline_us - at > 20, f"{name}: an answer at {at} us too close to the deadline {deadline_us}"
        else:
            at, events = math.ceil(deadline_us) + SILENCE_US, []
        now = at
        for ev in events:
            s.feed(decode(event_frame(ev)))
        writes = s.step(now / 1e6)
        step = {"at_us": now, "in": events, "out": [[w.frames, w.probe] for w in writes]}
        if not s.finished:
            step["deadline_us"] = round(s.deadline() * 1e6)
        steps.append(step)
        deliver(now, writes)
    result = "ok" if s.error is None else ("seq_old" if "SEQ_OLD" in s.error else "link_down")
    c = s.counters
    return {"name": name, "description": description, "window": window, "ahead": ahead, "timeout_ms": timeout_ms,
            "baud": baud, "retries": retries, "types": [int(t) for t in types], "first_seq": first_seq,
            "steps": steps, "result": result, "answered": [r is not None for r in s.results],
            "retransmissions": c.retransmissions, "timeouts": c.timeouts, "probes": c.probes}


def scenarios():
    M = MsgType.MOVE
    return [
        run("clean", "12 requests, nothing lost: 4 ahead of the answers, the window's 8 at most, a probe behind the "
            "last request"),
        run("clean_bursts", "the answers of each write arrive together", one_by_one=False),
        run("lost_request", "the 2nd request is lost: its followers are held (NAK HELD), the answer of the 3rd's "
            "HELD shows it lost, one resend, no timeout", lose_to={2}),
        run("lost_answer", "the 1st answer is lost: the 2nd answer shows it, one resend answered from memory",
            lose_back={1}),
        run("lost_last_request", "the last request is lost: the probe behind it shows it, no timeout", n=5,
            lose_to={5}),
        run("lost_resend", "a lost request's resend is lost too: the probe after the resend shows it", lose_to={2, 8}),
        run("lost_request_and_probe", "the last request and the probe behind it are lost: the timeout sends it "
            "again", n=4, lose_to={4, 5}),
        run("held_answers_lost", "a lost request's followers held, and the answers of their release lost: the "
            "later answers show them, each sent again once", lose_to={1}, lose_back={5, 6}),
        run("release_answer_lost", "the 1st request lost, its resend's answer lost too: the first answer of the "
            "release sends it again, the other answers of that release do not", lose_to={1}, lose_back={4}),
        run("damaged_request", "the 3rd request arrives damaged: NAK BAD_CRC (not counted), the HELD of its "
            "followers shows it lost", damage_to={3}),
        run("damaged_oldest", "the 1st request arrives damaged: a BAD_CRC NAK naming the oldest unanswered one "
            "sends it again", n=3, damage_to={1}),
        run("duplicated_answers", "answers delivered twice: the copies are stale", n=6, duplicate_back={1, 3, 4}),
        run("stale_and_foreign", "a NAK and an answer of SEQs not in flight, an answer of another type: ignored",
            n=4, extra={1: [["R", 0x10, int(M)], ["N", 0x90, "SEQ_GAP"], ["R", 0x21, int(MsgType.STATUS)]]}),
        run("stop_and_wait", "a window of 1: no probe, a lost answer costs a timeout", n=4, window=1,
            lose_back={2}),
        run("unpaced", "ahead 0: the whole window at once; a lost request", ahead=0, lose_to={3}),
        run("gap_beyond_the_firmware", "a host window of 10 over the firmware's 8, all at once, the 1st request "
            "lost: the 9th and 10th are NAKed SEQ_GAP (refused: sent again at once)", window=10, ahead=0, lose_to={1}),
        run("seq_wraps", "SEQs across 0xFF -> 0x00 with a lost request", first_seq=0xFC, lose_to={3}),
        run("slow_type", "CONFIG_SET waits 1 s for its answer: a lost one is sent again after it", n=3,
            types=[MsgType.CONFIG_SET] * 3, lose_back={2}),
        run("slow_baud", "at 250000 baud the deadlines are earlier; a lost answer behind a lost probe", n=6,
            baud=250000, lose_back={6, 7}),
        run("line_dies", "the line carries nothing from the 6th copy on: retries resends of the oldest, then "
            "link down", n=8, retries=3, dead_from=6),
        run("seq_old", "a NAK SEQ_OLD ends the stream at once", n=4, extra={2: [["N", 0x22, "SEQ_OLD"]]}),
    ]


def main():
    doc = {"description": "traces of the window sender (PROTOCOL.md Window, Probe, Pacing, Timeout): each scenario "
           "gives the sender's settings (window, ahead, timeout_ms, baud, retries), the requests' types (SEQs from "
           "first_seq on), then steps: at_us the time since the start, in the frames received before it (R seq type: "
           "a response of zeros; N seq reason: a NAK), out the writes it then makes ([request indices, probe SEQ or "
           "null]), deadline_us its deadline after the step (within 3 us); the first step is the start. result "
           "(ok, link_down, seq_old), answered and the counters close it. Written by make_sender_traces.py from the "
           "Python sender; the C++ sender must reproduce every step",
           "vectors": scenarios()}
    with open(os.path.join(HERE, "sender_traces.json"), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


if __name__ == "__main__":
    main()
