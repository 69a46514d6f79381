"""checks_link.py - handshake, framing, NAKs, resynchronisation after garbage, the window (order, at-most-once
execution over the last WINDOW requests, requests ahead of a gap held and run in order once it is filled, old
frames refused, streams)."""
import binascii
import random

from rbx1proto import frame, messages
from rbx1proto.messages import ALL_JOINTS_MASK, JOINTS, Cap, MsgType, State, Status

from .board import brief
from .runner import check, expect


def naks(events, seq=None):
    """(seq, reason) of every NAK frame among events (optionally only for seq)."""
    out = []
    for ev in events:
        if isinstance(ev, frame.Frame) and ev.type == MsgType.NAK and (seq is None or ev.seq == seq):
            out.append((ev.seq, messages.unpack_nak(ev.payload)["reason"]))
    return out


def responses(events, msg_type, seq):
    return [ev for ev in events if isinstance(ev, frame.Frame) and ev.type == (msg_type | 0x80) and ev.seq == seq]


def unchanged(board, before):
    """Nothing was executed: same moves_done and positions, queue empty, IDLE."""
    s = board.status()
    expect(s["moves_done"] == before["moves_done"], f"moves_done changed: {before['moves_done']} -> {s['moves_done']}")
    expect(s["position"] == before["position"], f"positions changed: {before['position']} -> {s['position']}")
    expect(s["state"] == State.IDLE and s["queue_free"] == board.queue_size, f"something was queued: {brief(s)}")


@check("handshake")
def handshake(b):
    r = b.ok(MsgType.HELLO, proto_version=messages.PROTO_VERSION)
    expect(r["proto_version"] == messages.PROTO_VERSION, f"proto_version {r['proto_version']}")
    expect(r["joints"] == JOINTS, f"joints {r['joints']}")
    expect(r["queue_size"] >= 2, f"queue_size {r['queue_size']}")
    expect(r["capabilities"] & ~int(sum(Cap)) == 0, f"unknown capability bits {r['capabilities']:#06x}")
    expect(1 <= r["window"] <= 64, f"window {r['window']}")
    # last_seq is the SEQ of the last executed request, so the host can continue after it.
    seq = b.link.seq
    b.status()
    r = b.ok(MsgType.HELLO, proto_version=messages.PROTO_VERSION)
    expect(r["last_seq"] == seq, f"last_seq {r['last_seq']}, the previous request had SEQ {seq}")
    r = b.refused(MsgType.HELLO, Status.BAD_VERSION, proto_version=messages.PROTO_VERSION + 1)
    expect(r["proto_version"] == messages.PROTO_VERSION and r["joints"] == JOINTS,
           f"BAD_VERSION fields not filled: {r}")


@check("response_time")
def response_time(b):
    # Hosts retransmit after 100 ms: a device must answer well within it. The median keeps a busy test machine's
    # scheduling spikes out of the verdict; a simulator's round trips count on its own clock (--clock-file).
    times = []
    for _ in range(15):
        t = b.now()
        b.status()
        times.append(b.now() - t)
    times.sort()
    median = times[len(times) // 2]
    expect(median < 0.05, f"median STATUS round trip {median * 1000:.1f} ms (all: {[round(x * 1000) for x in times]})")


@check("status_and_heartbeat")
def status_and_heartbeat(b):
    s = b.status()
    expect(s["state"] == State.IDLE, f"not IDLE after prepare: {brief(s)}")
    expect(s["homed"] == ALL_JOINTS_MASK and s["enabled"] == 1, f"SET_POSITION/ENABLE not reflected: {brief(s)}")
    expect(s["position"] == [0] * JOINTS and s["queue_free"] == b.queue_size, brief(s))
    b.ok(MsgType.HEARTBEAT)
    b.ok(MsgType.SET_POSITION, position=[11, -22, 33, -44, 55, -66])
    expect(b.status()["position"] == [11, -22, 33, -44, 55, -66], "SET_POSITION not reflected in STATUS")


@check("unknown_type_nak")
def unknown_type_nak(b):
    before = b.status()
    # A frame of no request type is NAKed UNKNOWN_TYPE whatever its SEQ and takes no place in the order (PROTOCOL.md
    # "Window"): the next request keeps the SEQ the unknown ones carried and runs (a used SEQ would be SEQ_OLD).
    seq = b.link.seq
    for t in (0x33, 0x7F, 0x82):  # unknown, NAK (firmware only), a response type
        for s in (seq, (seq + 3) & 0xFF, (seq - 20) & 0xFF):  # the next SEQ, a gap, the past
            ev = b.exchange_raw(frame.encode(s, t, b""), until=lambda e: naks(e), timeout=2.0)
            expect(naks(ev) == [(s, Status.UNKNOWN_TYPE)], f"type {t:#04x} seq {s}: expected NAK UNKNOWN_TYPE, got {ev}")
    ev = b.exchange_raw(frame.encode(seq, MsgType.STATUS, b""),
                        until=lambda e: naks(e) or responses(e, MsgType.STATUS, seq), timeout=2.0)
    expect(len(responses(ev, MsgType.STATUS, seq)) == 1 and not naks(ev),
           f"STATUS with the unknown frames' SEQ {seq}: expected its response, got {ev}")
    b.link.seq = (seq + 1) & 0xFF
    b.exchange_raw(frame.encode(b.link.seq, 0x33, b""), until=lambda e: naks(e), timeout=2.0)
    r = b.ok(MsgType.HELLO, proto_version=messages.PROTO_VERSION)
    expect(r["last_seq"] == seq, f"HELLO last_seq {r['last_seq']}, expected the STATUS's {seq}")
    unchanged(b, before)


@check("wrong_length_response")
def wrong_length_response(b):
    # PROTOCOL.md: a CRC-valid frame of a known type with a wrong payload length is a request; it is answered (not
    # NAKed: resending the same bytes cannot help) with a full-length response whose status is BAD_LENGTH.
    before = b.status()
    for t, payload in ((MsgType.STATUS, b"\x00"), (MsgType.MOVE, bytes(25)), (MsgType.MOVE, bytes(27))):
        seq = b.next_seq()
        ev = b.exchange_raw(frame.encode(seq, t, payload), until=lambda e: responses(e, t, seq) or naks(e))
        what = f"{t.name} with {len(payload)} payload bytes"
        expect(not naks(ev), f"{what}: NAKed, expected a BAD_LENGTH response: {ev}")
        r = responses(ev, t, seq)
        expect(len(r) == 1, f"{what}: expected one response with SEQ {seq}, got {ev}")
        expect(r[0].payload[:1] == bytes([Status.BAD_LENGTH]), f"{what}: status {r[0].payload[:1].hex()}, "
                                                                f"expected BAD_LENGTH: {ev}")
        expect(len(r[0].payload) == messages.response_len(t),
               f"{what}: response of {len(r[0].payload)} bytes, expected the full {messages.response_len(t)}")
    unchanged(b, before)


@check("corrupt_frame_nak")
def corrupt_frame_nak(b):
    before = b.status()
    # The next SEQ, not consumed: a frame the firmware rejects takes no place in its order.
    seq, wire = b.frame(MsgType.MOVE, seq=b.link.seq, target=[100] * JOINTS, duration_ms=0)
    # Two damaged bytes each time: the parity corrects one (damaged_byte_corrected), so two are what a frame the
    # firmware must reject takes.
    crc = len(wire) - frame.OVERHEAD + 4  # the first CRC byte
    for what, damage in (("a payload bit and a CRC bit", ((6, 0x01), (crc + 1, 0x80))),
                         ("two CRC bytes", ((crc, 0xFF), (crc + 3, 0xFF)))):
        bad = bytearray(wire)
        for i, x in damage:
            bad[i] ^= x
        ev = b.exchange_raw(bytes(bad), until=lambda e: naks(e))
        expect(naks(ev) == [(seq, Status.BAD_CRC)], f"{what}: expected NAK BAD_CRC seq {seq}, got {ev}")
    unchanged(b, before)


@check("damaged_byte_corrected")
def damaged_byte_corrected(b):
    # Version 5's parity (PROTOCOL.md "Frame"): any one damaged byte after SYNC, LEN included, is corrected and the
    # request runs, once.
    before = b.status()
    n = len(frame.encode(0, MsgType.MOVE, bytes(messages.request_len(MsgType.MOVE))))
    for k, at in enumerate((1, 2, 3, 9, n - 5, n - 1)):  # LEN, SEQ, TYPE, payload, CRC, parity
        seq, wire = b.frame(MsgType.MOVE, target=[10 * (k + 1), 0, 0, 0, 0, 0], duration_ms=0)
        bad = bytearray(wire)
        bad[at] ^= 0x5C
        ev = b.exchange_raw(bytes(bad), until=lambda e: naks(e) or responses(e, MsgType.MOVE, seq))
        r = responses(ev, MsgType.MOVE, seq)
        expect(len(r) == 1 and r[0].payload[0] == Status.OK and not naks(ev),
               f"byte {at} of {n} damaged: expected the MOVE accepted, got {ev}")
    s = b.wait_idle()
    expect(s["moves_accepted"] == before["moves_accepted"] + 6, f"expected 6 MOVEs accepted once each: {brief(s)}")
    expect(s["position"][0] == 60, f"position {s['position']}, expected joint 1 at 60")


@check("crc16_blind_corruption_nak")
def crc16_blind_corruption_nak(b):
    # A line error that protocol version 3's CRC-16 could not see: the bits of its generator (0x11021) flipped in
    # joint 1's target leave the CRC-16 over LEN..PAYLOAD unchanged. The CRC-32 must reject it (NAK BAD_CRC, nothing
    # run); the frame as sent still runs afterwards (the rejection left the order alone).
    before = b.status()
    seq, wire = b.frame(MsgType.MOVE, seq=b.link.seq, target=[40, 0, 0, 0, 0, 0], duration_ms=0)
    bad = bytearray(wire)
    for i, x in enumerate(b"\x01\x10\x21"):
        bad[4 + i] ^= x
    body = slice(1, len(wire) - frame.OVERHEAD + 4)  # LEN..PAYLOAD
    expect(binascii.crc_hqx(bytes(bad[body]), 0xFFFF) == binascii.crc_hqx(wire[body], 0xFFFF), "not a CRC-16 collision")
    ev = b.exchange_raw(bytes(bad), until=lambda e: naks(e) or responses(e, MsgType.MOVE, seq))
    expect(naks(ev) == [(seq, Status.BAD_CRC)], f"expected NAK BAD_CRC seq {seq}, got {ev}")
    s = b.status()
    expect(s["moves_accepted"] == before["moves_accepted"], f"the corrupt MOVE was accepted: {brief(s)}")
    unchanged(b, before)
    seq = b.next_seq()
    wire = frame.encode(seq, MsgType.MOVE, wire[body][3:])
    ev = b.exchange_raw(wire, until=lambda e: responses(e, MsgType.MOVE, seq))
    r = responses(ev, MsgType.MOVE, seq)
    expect(len(r) == 1 and r[0].payload[0] == Status.OK, f"the MOVE as sent was not accepted: {ev}")
    s = b.wait_idle()
    expect(s["position"][0] == 40, f"position {s['position']}, expected joint 1 at 40")


@check("length_over_max_nak")
def length_over_max_nak(b):
    before = b.status()
    seq = b.link.seq  # rejected frames take no place in the order
    # A TYPE of no fixed payload length: nothing can repair LEN, so the rejection comes as soon as TYPE is in.
    ev = b.exchange_raw(bytes([frame.SYNC, frame.MAX_PAYLOAD + 1, seq, 0x55]), until=lambda e: naks(e))
    expect([r for _, r in naks(ev)] == [Status.BAD_LENGTH], f"LEN 59, TYPE 0x55: expected NAK BAD_LENGTH, got {ev}")
    # A MOVE whose LEN reads 59 and one more byte damaged: the reading with MOVE's own length fails too.
    _, wire = b.frame(MsgType.MOVE, seq=seq, target=[100] * JOINTS, duration_ms=0)
    bad = bytearray(wire)
    bad[1] = frame.MAX_PAYLOAD + 1
    bad[8] ^= 0x01
    ev = b.exchange_raw(bytes(bad), until=lambda e: naks(e))
    expect([r for _, r in naks(ev)] == [Status.BAD_LENGTH], f"MOVE with LEN 59: expected NAK BAD_LENGTH, got {ev}")
    unchanged(b, before)


@check("garbage_resync")
def garbage_resync(b):
    before = b.status()
    rng = random.Random(1)
    clean = bytes(rng.choice([x for x in range(256) if x != frame.SYNC]) for _ in range(300))
    b.link.send_raw(clean)
    r0 = b.link.retransmissions
    b.status()
    expect(b.link.retransmissions == r0, "garbage without SYNC bytes cost a retransmission")
    # Garbage with SYNC bytes may hold the receiver in a false frame for up to the inter-byte timeout; the
    # Link's retransmission must then get through.
    noisy = bytes(rng.randrange(256) for _ in range(300)) + bytes([frame.SYNC] * 5)
    b.link.send_raw(noisy)
    b.status()
    unchanged(b, before)


@check("frame_hidden_in_corrupt_frame")
def frame_hidden_in_corrupt_frame(b):
    before = b.status()
    outer_seq = b.link.seq  # the outer frame is rejected: the hidden one is the next in order
    inner_seq, inner = b.frame(MsgType.STATUS)
    body = bytes([30, outer_seq, MsgType.MOVE]) + inner + bytes(30 - len(inner))
    outer = bytes([frame.SYNC]) + body + bytes(frame.OVERHEAD - 4)  # a wrong CRC
    ev = b.exchange_raw(outer, until=lambda e: responses(e, MsgType.STATUS, inner_seq) and naks(e))
    expect(naks(ev) == [(outer_seq, Status.BAD_CRC)], f"outer frame: expected NAK BAD_CRC, got {ev}")
    expect(len(responses(ev, MsgType.STATUS, inner_seq)) == 1, f"the hidden STATUS frame was not answered: {ev}")
    unchanged(b, before)


@check("partial_frame_timeout")
def partial_frame_timeout(b):
    seq, wire = b.frame(MsgType.STATUS, seq=b.link.seq)  # never completed: takes no place in the order
    b.link.send_raw(wire[:4])
    b.sleep(0.15)  # > 50 ms inter-byte timeout: the partial frame is dropped silently
    seq2, wire2 = b.frame(MsgType.STATUS)
    ev = b.exchange_raw(wire2, until=lambda e: responses(e, MsgType.STATUS, seq2), timeout=0.5)
    expect(len(responses(ev, MsgType.STATUS, seq2)) == 1, f"no answer after a timed-out partial frame: {ev}")
    expect(not naks(ev), f"the partial frame was not dropped by the inter-byte timeout: {naks(ev)}")


@check("partial_frame_rescanned")
def partial_frame_rescanned(b):
    # PROTOCOL.md: the inter-byte timeout drops a partial frame's SYNC and rescans the bytes after it, so a whole
    # frame that a truncated one swallowed is still found and answered; the truncated one is never executed.
    before = b.status()
    _, cut = b.frame(MsgType.MOVE, seq=b.link.seq, target=[100] * JOINTS, duration_ms=0)
    seq, wire = b.frame(MsgType.STATUS)
    ev = b.exchange_raw(cut[:10] + wire, until=lambda e: responses(e, MsgType.STATUS, seq), timeout=0.5)
    expect(len(responses(ev, MsgType.STATUS, seq)) == 1, f"the swallowed STATUS was not found by the rescan: {ev}")
    s = b.status()
    expect(s["moves_accepted"] == before["moves_accepted"], f"the truncated MOVE was executed: {brief(s)}")


@check("duplicate_not_reexecuted")
def duplicate_not_reexecuted(b):
    before = b.status()
    target = [120, -80, 40, 0, -20, 10]
    seq, wire = b.frame(MsgType.MOVE, target=target, duration_ms=0)
    first = b.exchange_raw(wire, until=lambda e: responses(e, MsgType.MOVE, seq))
    again = b.exchange_raw(wire, until=lambda e: responses(e, MsgType.MOVE, seq))  # a retransmission
    r1, r2 = responses(first, MsgType.MOVE, seq), responses(again, MsgType.MOVE, seq)
    expect(len(r1) == 1 and r1[0].payload[0] == Status.OK, f"MOVE not accepted: {first}")
    expect(len(r2) == 1 and r2[0].payload == r1[0].payload, f"duplicate not answered with the same response: {again}")
    s = b.wait_idle()
    expect(s["moves_done"] == (before["moves_done"] + 1) & 0xFFFF,
           f"the duplicate was executed again: moves_done {before['moves_done']} -> {s['moves_done']}")
    expect(s["position"] == target, f"position {s['position']} != {target}")


@check("same_seq_new_crc_is_refused")
def same_seq_new_crc_is_refused(b):
    # A used SEQ with other bytes is not a retransmission and not the next in order: NAK SEQ_OLD, never run.
    before = b.status()
    seq, wire_a = b.frame(MsgType.MOVE, target=[50, 0, 0, 0, 0, 0], duration_ms=0)
    _, wire_b = b.frame(MsgType.MOVE, seq=seq, target=[90, 0, 0, 0, 0, 0], duration_ms=0)
    ev = b.exchange_raw(wire_a, until=lambda e: responses(e, MsgType.MOVE, seq))
    r = responses(ev, MsgType.MOVE, seq)
    expect(len(r) == 1 and r[0].payload[0] == Status.OK, f"MOVE not accepted: {ev}")
    ev = b.exchange_raw(wire_b, until=lambda e: naks(e) or responses(e, MsgType.MOVE, seq))
    expect(naks(ev) == [(seq, Status.SEQ_OLD)], f"expected NAK SEQ_OLD seq {seq}, got {ev}")
    s = b.wait_idle()
    expect(s["moves_accepted"] == (before["moves_accepted"] + 1) & 0xFFFF, f"moves_accepted {s['moves_accepted']}: "
                                                                           f"expected +1")
    expect(s["position"][0] == 50, f"position {s['position']}: the second frame was executed")


@check("new_host_same_seq_runs")
def new_host_same_seq_runs(b):
    # A host that starts its session with the very bytes of an earlier session (a tool run twice: HELLO with the
    # same SEQ, then the same request, both still in the window) is a new session, not a retransmission: its request
    # runs. Answered from memory, the MOVE would be acknowledged and never executed.
    before = b.wait_idle()
    seq = b.link.seq
    hello = frame.encode(seq, MsgType.HELLO, messages.pack_request(MsgType.HELLO, proto_version=messages.PROTO_VERSION))
    mseq = (seq + 1) & 0xFF
    move = frame.encode(mseq, MsgType.MOVE, messages.pack_request(MsgType.MOVE, target=[70, 0, 0, 0, 0, 0],
                                                                  duration_ms=0))
    for session in (1, 2):  # HELLO(seq), MOVE(seq + 1) to 70: byte for byte the same both times
        ev = b.exchange_raw(hello, until=lambda e: responses(e, MsgType.HELLO, seq))
        expect(responses(ev, MsgType.HELLO, seq), f"session {session}: HELLO seq {seq}: {ev}")
        ev = b.exchange_raw(move, until=lambda e: responses(e, MsgType.MOVE, mseq))
        r = responses(ev, MsgType.MOVE, mseq)
        expect(len(r) == 1 and r[0].payload[0] == Status.OK, f"session {session}: MOVE seq {mseq}: {ev}")
    b.link.seq = (seq + 2) & 0xFF
    s = b.wait_idle()
    expect(s["moves_accepted"] == (before["moves_accepted"] + 2) & 0xFFFF,
           f"moves_accepted {before['moves_accepted']} -> {s['moves_accepted']}: the second session's MOVE was "
           f"answered from the first session's memory and not run")
    expect(s["position"][0] == 70, f"position {s['position']}")


def move_frames(b, targets):
    """(seqs, wire frames) of MOVEs to targets[i] on joint 1, consecutive SEQs (consumed)."""
    seqs, wires = [], []
    for x in targets:
        seq, wire = b.frame(MsgType.MOVE, target=[x, 0, 0, 0, 0, 0], duration_ms=0)
        seqs.append(seq)
        wires.append(wire)
    return seqs, wires


@check("window_duplicates_never_rerun")
def window_duplicates_never_rerun(b):
    # PROTOCOL.md "Window": a full window of MOVEs back to back, then every one of them again (a go-back): each
    # duplicate gets its first answer and none runs again. Targets alternate, so a MOVE run twice would leave the
    # joint elsewhere: the final position and moves_accepted are exact.
    w = b.info["window"]
    before = b.status()
    targets = [40 if i % 2 == 0 else -40 for i in range(w - 1)] + [25]
    seqs, wires = move_frames(b, targets)
    ev = b.exchange_raw(b"".join(wires), until=lambda e: all(responses(e, MsgType.MOVE, q) for q in seqs), timeout=2)
    first = {q: responses(ev, MsgType.MOVE, q) for q in seqs}
    expect(all(len(r) == 1 and r[0].payload[0] == Status.OK for r in first.values()), f"window of MOVEs: {ev}")
    ev = b.exchange_raw(b"".join(wires), until=lambda e: all(responses(e, MsgType.MOVE, q) for q in seqs), timeout=2)
    for q in seqs:
        again = responses(ev, MsgType.MOVE, q)
        expect(len(again) == 1 and again[0].payload == first[q][0].payload,
               f"seq {q}: duplicate not answered with its first answer: {again} vs {first[q]}")
    expect(not naks(ev), f"duplicates NAKed: {naks(ev)}")
    # The oldest of them, older than the window once more requests were answered: refused, never run.
    s = b.wait_idle()
    ev = b.exchange_raw(wires[0], until=lambda e: naks(e) or responses(e, MsgType.MOVE, seqs[0]))
    expect(naks(ev) == [(seqs[0], Status.SEQ_OLD)], f"a MOVE older than the window: expected NAK SEQ_OLD, got {ev}")
    s = b.wait_idle()
    expect(s["moves_accepted"] == (before["moves_accepted"] + w) & 0xFFFF,
           f"moves_accepted {before['moves_accepted']} -> {s['moves_accepted']}, expected +{w}")
    expect(s["moves_done"] == (before["moves_done"] + w) & 0xFFFF, f"moves_done {s['moves_done']}: expected +{w}")
    expect(s["position"] == [25, 0, 0, 0, 0, 0], f"position {s['position']}: a duplicate ran again")


@check("window_gap_held")
def window_gap_held(b):
    # PROTOCOL.md "Window": requests ahead of a missing one, within the window, are held (NAK HELD), not run; a copy
    # of a held one is answered HELD again and kept once; one a whole window ahead is a gap (NAK SEQ_GAP). The
    # missing one runs, then the held ones in SEQ order, each once. Targets 30, 60, 45: run out of order or twice,
    # the joint would end elsewhere or moves_accepted would show it.
    w = b.info["window"]
    before = b.status()
    seqs, wires = move_frames(b, [30, 60, 45])
    beyond = (seqs[0] + w) & 0xFF
    _, far = b.frame(MsgType.MOVE, seq=beyond, target=[999, 0, 0, 0, 0, 0], duration_ms=0)
    ev = b.exchange_raw(wires[2] + wires[1] + wires[1] + far, until=lambda e: len(naks(e)) >= 4, timeout=2)
    want = [(seqs[2], Status.HELD), (seqs[1], Status.HELD), (seqs[1], Status.HELD), (beyond, Status.SEQ_GAP)]
    expect(naks(ev) == want, f"held and beyond: expected NAKs {want}, got {ev}")
    expect(not [e for e in ev if isinstance(e, frame.Frame) and e.type & 0x80], f"a held request was answered: {ev}")
    ev = b.exchange_raw(wires[0], until=lambda e: all(responses(e, MsgType.MOVE, q) for q in seqs), timeout=2)
    order = [e.seq for e in ev if isinstance(e, frame.Frame) and e.type == MsgType.MOVE | 0x80]
    expect(order == seqs, f"the filled gap: expected answers for SEQs {seqs} in that order, got {ev}")
    expect(all(responses(ev, MsgType.MOVE, q)[0].payload[0] == Status.OK for q in seqs if responses(ev, MsgType.MOVE, q)),
           f"not accepted: {ev}")
    s = b.wait_idle()
    expect(s["moves_accepted"] == (before["moves_accepted"] + 3) & 0xFFFF, f"moves_accepted: {brief(s)}, expected +3")
    expect(s["position"][0] == 45, f"position {s['position']}: held requests ran out of order")


@check("probe_answered_in_order")
def probe_answered_in_order(b):
    # PROTOCOL.md "Probe": a frame of TYPE 0x7F with no payload is NAKed UNKNOWN_TYPE in its turn, after the
    # answers of every frame before it, and changes nothing: a held request stays held, the order does not move.
    before = b.status()
    seqs, wires = move_frames(b, [30, 60])
    pseq = (seqs[0] - 1) & 0xFF
    probe = frame.encode(pseq, MsgType.NAK, b"")
    ev = b.exchange_raw(wires[1] + probe, until=lambda e: len(naks(e)) >= 2, timeout=2)
    want = [(seqs[1], Status.HELD), (pseq, Status.UNKNOWN_TYPE)]
    expect(naks(ev) == want, f"held request then probe: expected NAKs {want}, got {ev}")
    ev = b.exchange_raw(wires[0] + probe, until=lambda e: naks(e), timeout=2)
    kinds = [(e.type, e.seq) for e in ev if isinstance(e, frame.Frame)]
    want = [(MsgType.MOVE | 0x80, seqs[0]), (MsgType.MOVE | 0x80, seqs[1]), (MsgType.NAK, pseq)]
    expect(kinds == want and naks(ev) == [(pseq, Status.UNKNOWN_TYPE)],
           f"the gap filled, then a probe: expected {want} in that order, got {ev}")
    s = b.wait_idle()
    expect(s["moves_accepted"] == (before["moves_accepted"] + 2) & 0xFFFF, f"moves_accepted: {brief(s)}, expected +2")
    expect(s["position"][0] == 60, f"position {s['position']}: the held request did not run after the filler")


@check("window_held_dropped_by_estop")
def window_held_dropped_by_estop(b):
    # An ESTOP drops the held requests, never run: after its answer each is NAKed SEQ_GAP. Filling the gap then
    # runs the missing one alone (refused: the e-stop latched); the dropped one, sent again, runs once.
    before = b.status()
    seqs, wires = move_frames(b, [30, 60])
    ev = b.exchange_raw(wires[1], until=lambda e: naks(e), timeout=2)
    expect(naks(ev) == [(seqs[1], Status.HELD)], f"expected NAK HELD seq {seqs[1]}, got {ev}")
    eseq, estop = b.frame(MsgType.ESTOP)
    ev = b.exchange_raw(estop, until=lambda e: responses(e, MsgType.ESTOP, eseq) and naks(e), timeout=2)
    kinds = [(e.type, e.seq) for e in ev if isinstance(e, frame.Frame)]
    expect(kinds == [(MsgType.ESTOP | 0x80, eseq), (MsgType.NAK, seqs[1])] and naks(ev) == [(seqs[1], Status.SEQ_GAP)],
           f"ESTOP with a held request: expected its answer then NAK SEQ_GAP seq {seqs[1]}, got {ev}")
    # The missing one and the dropped one again: exactly one answer each (the dropped one, had it stayed held,
    # would be answered when the gap is filled and again as a duplicate; 2 s for that second answer to show).
    ev = b.exchange_raw(wires[0] + wires[1], until=lambda e: len(responses(e, MsgType.MOVE, seqs[1])) >= 2,
                        timeout=2)
    for q in seqs:
        r = responses(ev, MsgType.MOVE, q)
        expect(len(r) == 1 and r[0].payload[0] == Status.FAULT_ACTIVE,
               f"seq {q} after the ESTOP: expected one answer FAULT_ACTIVE, got {ev}")
    s = b.status()
    expect(s["moves_accepted"] == before["moves_accepted"], f"moves_accepted: {brief(s)}: a dropped request ran")
    expect(s["position"] == before["position"], f"position {s['position']}: a dropped request moved the arm")


@check("window_stream")
def window_stream(b):
    # rbx1proto's Link.stream keeps the window in flight: 3 windows of MOVEs, each answered OK once, run in order.
    w = b.info["window"]
    b.link.window = w
    n = min(3 * w, b.queue_size)
    before = b.status()
    rs = b.link.stream([(MsgType.MOVE, dict(target=[10 * (i + 1), -i, 0, 0, 0, i], duration_ms=0)) for i in range(n)])
    expect([r["status"] for r in rs] == [Status.OK] * n, f"stream answers: {[r['status'] for r in rs]}")
    s = b.wait_idle()
    expect(s["moves_accepted"] == (before["moves_accepted"] + n) & 0xFFFF, f"moves_accepted: {brief(s)}")
    expect(s["moves_done"] == (before["moves_done"] + n) & 0xFFFF, f"moves_done: {brief(s)}")
    expect(s["position"] == [10 * n, -(n - 1), 0, 0, 0, n - 1], f"position {s['position']}")
