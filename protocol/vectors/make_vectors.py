#!/usr/bin/python3
"""make_vectors.py - writes the shared test vectors (messages, streams, random_streams, bad_payloads, fec,
crc, window .json) here.

Each stream's expected events are written down by construction here (not read back from a decoder; random_streams
alone are the Python decoder's, for the C one to agree with); the script then checks that the Python decoder agrees
before writing, and both the C and the Python tests check every vector.
Run after a change to messages.json: /usr/bin/python3 protocol/vectors/make_vectors.py
"""
import binascii
import json
import os
import random
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "python"))
from rbx1proto import frame  # noqa: E402
from rbx1proto.messages import MsgType, Status, State, Fault, Input, Cap, Key, PROTO_VERSION, GLOBAL_JOINT  # noqa: E402
from rbx1proto import messages  # noqa: E402

I32_MIN, I32_MAX = -2**31, 2**31 - 1

# Sample fields per type: (request fields, response fields). Values exercise signs, extremes and 0xA5 bytes.
SAMPLES = {
    MsgType.HELLO: ({"proto_version": PROTO_VERSION},
                    {"status": Status.OK, "proto_version": PROTO_VERSION, "fw_major": 1, "fw_minor": 2, "fw_patch": 3,
                     "joints": 6, "queue_size": 16,
                     "capabilities": int(Cap.GRIPPER | Cap.EEPROM_CONFIG | Cap.ESTOP_INPUT | Cap.SIMULATED),
                     "last_seq": 0xA5, "window": 8}),
    MsgType.STATUS: ({},
                     {"status": Status.OK, "state": State.MOVING, "faults": int(Fault.EEPROM_DEFAULTS),
                      "homed": 0x3F, "inputs": int(Input.LIMIT_J2 | Input.ESTOP), "enabled": 1, "queue_free": 15,
                      "moves_done": 0xA5A5, "gripper_us": 1500,
                      "position": [0, -1, 123456, -123456, I32_MAX, I32_MIN],
                      "moves_accepted": 0xA5A7, "moves_flushed": 1}),
    MsgType.HEARTBEAT: ({}, {"status": Status.OK}),
    MsgType.MOVE: ({"target": [1000, -2000, 0, 0xA5A5A5, -0xA5, 42], "duration_ms": 1500},
                   {"status": Status.OK, "queue_free": 14}),
    MsgType.GRIPPER: ({"pulse_us": 2000, "dwell_ms": 300}, {"status": Status.OK, "queue_free": 13}),
    MsgType.HOME: ({"joint_mask": 0}, {"status": Status.OK}),
    MsgType.STOP: ({}, {"status": Status.OK}),
    MsgType.ESTOP: ({}, {"status": Status.OK}),
    MsgType.CLEAR_FAULT: ({}, {"status": Status.ESTOP_ACTIVE}),
    MsgType.ENABLE: ({"enable": 1}, {"status": Status.FAULT_ACTIVE}),
    MsgType.SET_POSITION: ({"position": [I32_MIN, I32_MAX, -1, 1, 0, -0x5A5A5A5A]}, {"status": Status.OK}),
    MsgType.CONFIG_GET: ({"joint": GLOBAL_JOINT, "key": Key.HEARTBEAT_MS}, {"status": Status.OK, "value": 1000}),
    MsgType.CONFIG_SET: ({"joint": 2, "key": Key.SOFT_MIN, "value": -100000}, {"status": Status.SOFT_LIMIT}),
    MsgType.CONFIG_RESET: ({}, {"status": Status.EEPROM_ERROR}),
}


def jsonable(fields):
    return {k: (list(map(int, v)) if isinstance(v, list) else int(v)) for k, v in fields.items()}


def message_vectors():
    out = []
    seq = 0
    for t in MsgType:
        if t == MsgType.NAK:
            continue
        req, resp = SAMPLES[t]
        for kind, fields, ftype, pack in (("request", req, int(t), messages.pack_request),
                                          ("response", resp, int(t) | 0x80, messages.pack_response)):
            payload = pack(t, **fields)
            wire = frame.encode(seq, ftype, payload)
            out.append({"name": f"{t.name} {kind}", "kind": kind, "msg": int(t), "type": ftype, "seq": seq,
                        "fields": jsonable(fields), "payload": payload.hex(), "wire": wire.hex(),
                        "crc": frame.crc32(wire[1:-6])})
        seq = (seq + 37) & 0xFF  # vary SEQ, and pass through 0xA5-ish values
    for seq, reason in ((5, Status.BAD_CRC), (0xA5, Status.BAD_LENGTH), (255, Status.UNKNOWN_TYPE)):
        payload = messages.pack_nak(reason)
        wire = frame.encode(seq, MsgType.NAK, payload)
        out.append({"name": f"NAK {reason.name}", "kind": "nak", "msg": int(MsgType.NAK), "type": int(MsgType.NAK),
                    "seq": seq, "fields": {"reason": int(reason)}, "payload": payload.hex(), "wire": wire.hex(),
                    "crc": frame.crc32(wire[1:-6])})
    return out


def ev_frame(b):
    """Expected frame event for an encoded frame b."""
    n = b[1]
    return {"frame": {"seq": b[2], "type": b[3], "payload": b[4:4 + n].hex(),
                      "crc": int.from_bytes(b[4 + n:8 + n], "little")}}


def crc16_collision():
    """(sent, received, target): a MOVE (SEQ 7, targets 1..6) and the same frame after a line error whose CRC-16 over
    LEN..PAYLOAD still matches (the bits of the CRC-16 generator 0x11021 flipped: a multiple of the generator leaves
    any CRC-16/CCITT-FALSE unchanged), and joint 1's target as the receiver would read it."""
    sent = frame.encode(7, MsgType.MOVE, messages.pack_request(MsgType.MOVE, target=[1, 2, 3, 4, 5, 6], duration_ms=0))
    got = bytearray(sent)
    for i, x in enumerate(b"\x01\x10\x21"):
        got[4 + i] ^= x  # the first target's low three bytes
    got = bytes(got)
    body = slice(1, len(sent) - 6)
    assert binascii.crc_hqx(got[body], 0xFFFF) == binascii.crc_hqx(sent[body], 0xFFFF)  # CRC-16 blind to it
    assert frame.crc32(got[body]) != frame.crc32(sent[body]) and got[-6:] == sent[-6:]
    return sent, got, messages.unpack_request(MsgType.MOVE, got[4:-6])["target"][0]


def as_events(items):
    """A decoder's Frames and Rejects in the vectors' event format."""
    return [{"frame": {"seq": e.seq, "type": e.type, "payload": e.payload.hex(), "crc": e.crc}}
            if isinstance(e, frame.Frame) else {"reject": {"status": Status(e.status).name, "seq": e.seq}}
            for e in items]


def ev_reject(status, seq):
    return {"reject": {"status": status.name, "seq": seq}}


def damage(b, errors):
    """b with each {index: error} XORed in."""
    c = bytearray(b)
    for i, x in errors.items():
        c[i] ^= x
    return bytes(c)


def two_errors_the_parity_miscorrects(b):
    """The first two damaged bytes (in SEQ, payload or CRC: TYPE kept, so no other length is tried) whose syndromes
    point at one byte after LEN: the corrected reading "corrects" it, and the CRC still refuses. Returns (errors,
    located index in the frame)."""
    n = len(b)
    for i in [2] + list(range(4, n - 2)):
        for j in range(max(i + 1, 4), n - 2):
            for x in range(1, 256):
                got = damage(b, {i: x, j: 0x81})
                found = frame.fec_locate(got[1:])
                if isinstance(found, tuple) and found[0] > 0 and 0xA5 not in got[1:]:
                    fixed = damage(got, {1 + found[0]: found[1]})
                    assert fixed != b and frame.crc32(fixed[1:-6]) != int.from_bytes(fixed[-6:-2], "little")
                    return {i: x, j: 0x81}, 1 + found[0]
    raise AssertionError("no miscorrected pair")


def stream_vectors():
    move = frame.encode(7, MsgType.MOVE, messages.pack_request(MsgType.MOVE, target=[1, 2, 3, 4, 5, 6], duration_ms=0))
    short = frame.encode(7, MsgType.MOVE | 0x80, messages.pack_response(MsgType.MOVE, status=0, queue_free=14))
    status = frame.encode(8, MsgType.STATUS)
    hello_resp = frame.encode(9, MsgType.HELLO | 0x80, messages.pack_response(MsgType.HELLO, **SAMPLES[MsgType.HELLO][1]))
    nak = frame.encode(3, MsgType.NAK, messages.pack_nak(Status.BAD_CRC))
    sync_seq = frame.encode(0xA5, MsgType.SET_POSITION, messages.pack_request(
        MsgType.SET_POSITION, position=[-0x5A5A5A5B, 0xA5, 0xA5A5, 0xA5A5A5, 0, 0]))
    assert sync_seq.count(0xA5) >= 8
    # Frames whose CRC, and whose parity, contain 0xA5 (search SEQ for them).
    crc_a5 = next(f for f in (frame.encode(s, t) for t in MsgType for s in range(256)) if 0xA5 in f[-6:-2])
    par_a5 = next(f for f in (frame.encode(s, MsgType.STATUS) for s in range(256)) if 0xA5 in f[-2:])
    maxf = frame.encode(1, 0x55, bytes(range(58)))  # longest payload; unknown TYPE is the firmware's business
    empty_unknown = frame.encode(2, 0x00, b"")
    assert 0xA5 not in move[1:] and 0xA5 not in short[1:] and 0xA5 not in status[1:]
    # Outer frame with two damaged bytes (beyond the parity) whose payload carries a whole valid frame.
    inner = status
    outer_ok = frame.encode(0x21, MsgType.GRIPPER, b"\x00" * 3 + inner + b"\x11" * 3)
    outer_bad = damage(outer_ok, {len(outer_ok) - 4: 0x01, 4: 0x40})
    # A NAK (TYPE 0x7F: no fixed length) whose LEN was hit: LEN 11 instead of 1, so the candidate swallows the next
    # frame, and no reading with TYPE's length exists.
    nak_len_hit = damage(nak, {1: 0x0A})

    S = []

    def add(name, description, wire, events, pending=False, after_timeout=(), then=None):
        v = {"name": name, "description": description, "wire": wire.hex(), "events": events, "pending": pending,
             "after_timeout": list(after_timeout)}
        if then is not None:  # (wire, events): bytes fed after the timeout, and their events
            v["then"] = {"wire": then[0].hex(), "events": then[1]}
        S.append(v)

    add("single_move", "one MOVE request (36 bytes on the wire)", move, [ev_frame(move)])
    add("empty_payload", "STATUS request: LEN 0, 10 bytes", status, [ev_frame(status)])
    add("max_payload", "58-byte payload, 68-byte frame", maxf, [ev_frame(maxf)])
    add("unknown_type", "a CRC-valid frame of an unknown TYPE is delivered (the firmware NAKs UNKNOWN_TYPE)",
        empty_unknown, [ev_frame(empty_unknown)])
    add("back_to_back", "STATUS, MOVE, HELLO response, NAK with no gap", status + move + hello_resp + nak,
        [ev_frame(status), ev_frame(move), ev_frame(hello_resp), ev_frame(nak)])
    add("sync_in_payload_and_seq", "SEQ 0xA5 and 0xA5 bytes in the payload", sync_seq, [ev_frame(sync_seq)])
    add("sync_in_crc", "a CRC byte equal to SYNC", crc_a5, [ev_frame(crc_a5)])
    add("skip_sync_in_parity_then_frame", "a STATUS whose parity holds 0xA5, then a MOVE at once: the STATUS is "
        "delivered at its last CRC byte and its 2 parity bytes are skipped (never hunted as a SYNC), the MOVE follows",
        par_a5 + move, [ev_frame(par_a5), ev_frame(move)])
    add("garbage_prefix", "garbage without SYNC before a frame", bytes([0x00, 0xFF, 0x13, 0x37, 0x5A, 0x80]) + move,
        [ev_frame(move)])
    add("garbage_with_sync_bad_length", "garbage A5 3B 07: LEN 59, TYPE read from the MOVE's SYNC (0xA5, no fixed "
        "length) rejected at once (BAD_LENGTH, SEQ 7), then the frame",
        bytes([0x01, 0xA5, 0x3B, 0x07]) + move, [ev_reject(Status.BAD_LENGTH, 7), ev_frame(move)])
    add("lone_sync_before_frame", "a stray SYNC: A5 A5 1A 07 reads LEN 0xA5 and TYPE 07 (STOP, fixed length 0): "
        "rejected once its 10-byte reading with LEN 0 fails (SEQ 0x1A), the frame found by resuming at the byte "
        "after the stray SYNC", bytes([0xA5]) + move, [ev_reject(Status.BAD_LENGTH, move[1]), ev_frame(move)])
    add("bad_length_64", "LEN 64 (TYPE 0xA5, no fixed length) rejected, the valid frame after it found",
        bytes([0xA5, 64, 0x33]) + status, [ev_reject(Status.BAD_LENGTH, 0x33), ev_frame(status)])
    add("bad_length_255", "LEN 255 with TYPE 0x33 (no fixed length) rejected as soon as TYPE is in",
        bytes([0xA5, 0xFF, 0x00, 0x33]), [ev_reject(Status.BAD_LENGTH, 0)])
    add("bad_length_no_type", "LEN 255 and SEQ, then nothing: undecided until TYPE arrives; the timeout drops it "
        "silently", bytes([0xA5, 0xFF, 0x00]), [], pending=True)
    add("bad_length_no_seq", "LEN 200 then nothing: undecided until the TYPE byte arrives", bytes([0xA5, 200]), [],
        pending=True)
    add("bad_crc", "MOVE with two CRC bytes damaged (one more than the parity corrects)",
        damage(move, {len(move) - 3: 0x01, len(move) - 5: 0x01}), [ev_reject(Status.BAD_CRC, 7)])
    add("bad_crc_then_valid", "MOVE with two payload bits flipped in two bytes, then a valid STATUS",
        damage(move, {10: 0x80, 20: 0x02}) + status, [ev_reject(Status.BAD_CRC, 7), ev_frame(status)])
    add("valid_hidden_in_corrupt", "a frame with two damaged bytes whose payload holds a whole valid frame: "
        "rejected, then the inner frame found by the rescan; the outer frame's bytes after it start a candidate (the "
        "byte after a frame is read as a SYNC), pending until the timeout drops it silently", outer_bad,
        [ev_reject(Status.BAD_CRC, 0x21), ev_frame(inner)], pending=True)
    add("corrupt_len_swallows_next", "a NAK with LEN hit (11 instead of 1; TYPE 0x7F has no fixed length, so LEN "
        "cannot be repaired): its candidate ends inside the next MOVE; rejected, the MOVE found by the rescan",
        nak_len_hit + move, [ev_reject(Status.BAD_CRC, 3), ev_frame(move)])
    add("truncated", "a MOVE cut inside its CRC: nothing yet, frame pending; the timeout drops it", move[:-4], [],
        pending=True)
    add("crc16_collision", "a MOVE hit by a line error that CRC-16/CCITT-FALSE (protocol version 3) cannot see: "
        "bytes 01 10 21 (the generator x^16+x^12+x^5+1) XORed into the first target, so joint 1's target reads "
        f"{crc16_collision()[2]} instead of 1 and the CRC-16 over LEN..PAYLOAD is unchanged; three damaged bytes are "
        "beyond the parity, and the CRC-32 rejects it", crc16_collision()[1], [ev_reject(Status.BAD_CRC, 7)])
    add("truncated_header", "SYNC and LEN only", move[:2], [], pending=True)
    add("truncated_swallows_short_frame", "a MOVE cut after 10 bytes, then a STATUS: the STATUS bytes are taken as "
        "the MOVE's continuation; the 50 ms inter-byte timeout drops the MOVE's SYNC and the rescan finds the STATUS",
        move[:10] + status, [], pending=True, after_timeout=[ev_frame(status)])
    stray = frame.encode(0x33, MsgType.STATUS)
    assert stray[3] == MsgType.STATUS and frame.implied_len(stray[2]) < 0
    add("truncated_then_sync_noise", "a MOVE cut after 10 bytes, then a stray SYNC and a truncated STATUS (SEQ "
        "0x33): the timeout's rescan rejects the stray SYNC (LEN read as 0xA5, TYPE as 0x33: no fixed length) and "
        "drops the rest", move[:10] + b"\xa5" + stray[:4], [], pending=True,
        after_timeout=[ev_reject(Status.BAD_LENGTH, stray[1])])
    add("sync_noise", "four stray SYNCs then a frame: three rejected at their TYPE (0xA5, 0x00: no fixed length), "
        "the fourth (TYPE 0x08, ESTOP: length 0) once its reading with LEN 0 fails", bytes([0xA5] * 4) + status,
        [ev_reject(Status.BAD_LENGTH, 0xA5), ev_reject(Status.BAD_LENGTH, 0xA5), ev_reject(Status.BAD_LENGTH, 0xA5),
         ev_reject(Status.BAD_LENGTH, status[1]), ev_frame(status)])
    add("garbage_only", "bytes without SYNC: no event, nothing pending", bytes(range(0, 0xA5)), [])
    doc_move = frame.encode(7, MsgType.MOVE, messages.pack_request(
        MsgType.MOVE, target=[1000, -2000, 3000, -4000, 5000, 0], duration_ms=1500))
    doc_resp = frame.encode(7, MsgType.MOVE | 0x80, messages.pack_response(MsgType.MOVE, status=0, queue_free=14))
    doc_nak = frame.encode(7, MsgType.NAK, messages.pack_nak(Status.BAD_CRC))
    add("protocol_md_example", "the example in PROTOCOL.md: a MOVE, its response and a NAK",
        doc_move + doc_resp + doc_nak, [ev_frame(doc_move), ev_frame(doc_resp), ev_frame(doc_nak)])
    add("frames_around_garbage", "frame, garbage, frame", status + b"\x00\x01\x02" + nak, [ev_frame(status),
        ev_frame(nak)])

    # Version 5: one damaged byte corrected, in each region of a MOVE (LEN 26) and of a short frame (a MOVE response,
    # LEN 2), then a damaged LEN repaired from TYPE's length. Every one delivers the frame sent.
    for tag, b in (("move", move), ("short", short)):
        n = b[1]
        other_type = MsgType.STATUS if b[3] == MsgType.MOVE else MsgType.STATUS | 0x80  # a fixed length, another
        fixed = "corrected by the parity at the last parity byte, the frame delivered as sent"
        skipped = "the CRC holds, so the frame is delivered at its last CRC byte and the damaged parity skipped"
        regions = (("seq", 2, 0x5A, "SEQ", fixed),
                   ("type", 3, b[3] ^ other_type, f"TYPE (read as 0x{other_type:02x})",
                    f"the reading with 0x{other_type:02x}'s fixed length fails, then " + fixed),
                   ("payload", 4 + n // 2, 0xFF, "a payload byte", fixed), ("crc", 5 + n, 0x10, "CRC 1", fixed),
                   ("par0", 8 + n, 0x01, "PAR 0", skipped), ("par1", 9 + n, 0x80, "PAR 1", skipped))
        for region, i, x, what, how in regions:
            add(f"fec_{tag}_{region}_corrected", f"{len(b)}-byte frame (LEN {n}) with {what} damaged (XOR 0x{x:02x}): "
                + how, damage(b, {i: x}), [ev_frame(b)])
        for how, bad in (("smaller", n // 2 - 1 if n > 2 else 0), ("larger", n + 14), ("above_58", n | 0x80)):
            add(f"fec_{tag}_len_{how}_repaired", f"{len(b)}-byte frame with LEN {n} damaged to {bad}: the reading with "
                f"TYPE 0x{b[3]:02x}'s length ({n}) in place of LEN holds (syndromes 0, CRC), the frame delivered",
                damage(b, {1: n ^ bad}), [ev_frame(b)])
        follower = status if tag == "move" else move
        add(f"fec_{tag}_v4_then_silence", f"the {len(b)}-byte frame without its parity (version 4) then silence: "
            "delivered at its CRC, pending until the inter-byte timeout forgets the parity; a frame after it is read",
            b[:-2], [ev_frame(b)], pending=True, then=(follower, [ev_frame(follower)]))
        add(f"fec_{tag}_delivered_at_crc_then_frame", f"the {len(b)}-byte frame (delivered at its CRC) and at once "
            "another frame: the parity skipped, the next frame read", b + follower, [ev_frame(b), ev_frame(follower)])
        errors, at = two_errors_the_parity_miscorrects(b)
        add(f"fec_{tag}_two_bytes_rejected", f"{len(b)}-byte frame with bytes {sorted(errors)} damaged: the syndromes "
            f"point at byte {at}, and the frame so \"corrected\" fails its CRC: rejected BAD_CRC",
            damage(b, errors), [ev_reject(Status.BAD_CRC, b[2] ^ errors.get(2, 0))])
    add("fec_len_no_fixed_type_above_58", "a NAK (TYPE 0x7F: no fixed length) with LEN damaged above 58: rejected "
        "BAD_LENGTH at its TYPE, nothing to repair LEN from", damage(nak, {1: 0x40}), [ev_reject(Status.BAD_LENGTH, 3)])
    add("v4_frame_then_silence", "a version 4 frame (no parity) then silence: delivered at its CRC, the 2 parity "
        "bytes awaited (pending) until the inter-byte timeout forgets them; a frame after the timeout is read whole",
        move[:-2], [ev_frame(move)], pending=True, then=(status, [ev_frame(status)]))
    add("v4_frames_back_to_back", "two version 4 frames with no gap: the first is delivered at its CRC and the next "
        "frame's SYNC and LEN are skipped as its parity, so the second is not seen (a version 4 peer is heard only "
        "after silences); its SEQ starts a candidate (the byte after a frame is read as a SYNC) that the timeout "
        "drops silently", move[:-2] + status[:-2], [ev_frame(move)], pending=True)

    status9 = frame.encode(9, MsgType.STATUS)
    add("timeout_rescan_delivers_at_crc", "a MOVE cut after 10 bytes, then a STATUS without its parity: the timeout's "
        "rescan delivers the STATUS at its CRC, and its parity is no longer awaited after the timeout, so the next "
        "frame is read whole", move[:10] + status[:-2], [], pending=True, after_timeout=[ev_frame(status)],
        then=(status9, [ev_frame(status9)]))
    move2 = frame.encode(9, MsgType.MOVE, messages.pack_request(MsgType.MOVE, target=[6, 5, 4, 3, 2, 1], duration_ms=9))
    add("sync_damaged_after_frame", "a MOVE, then a MOVE whose SYNC is damaged: the byte after a delivered frame is "
        "read as a SYNC, so both are delivered", move + damage(move2, {0: 0x5A}), [ev_frame(move), ev_frame(move2)])
    add("sync_and_payload_damaged_after_frame", "a MOVE, then a MOVE whose SYNC and one payload byte are damaged: "
        "the second is corrected by its parity and delivered", move + damage(move2, {0: 0x01, 12: 0x40}),
        [ev_frame(move), ev_frame(move2)])
    add("sync_damaged_first_frame", "a MOVE whose SYNC is damaged with no frame before it: not seen (nothing, "
        "nothing pending)", damage(move2, {0: 0x01}), [])
    add("garbage_after_frame_silent", "a STATUS, a stray byte, then a MOVE: the stray byte starts a candidate (LEN "
        "read as 0xA5, TYPE as 0x1A: no fixed length), dropped without a rejection; the MOVE is found by the rescan",
        status + b"\x42" + move, [ev_frame(status), ev_frame(move)])
    bad9 = damage(status9, {4: 0x01, 6: 0x01})  # two CRC bytes: one more than the parity corrects
    add("corrupt_frame_after_frame_rejected", "a STATUS, then at once a STATUS (SEQ 9) with two CRC bytes damaged "
        "whose SYNC is intact: the byte after a frame is 0xA5, a real SYNC, so the corrupt frame is rejected BAD_CRC "
        "like any (the firmware NAKs it)", status + bad9, [ev_frame(status), ev_reject(Status.BAD_CRC, 9)])
    add("corrupt_frame_after_frame_damaged_sync_silent", "the same with its SYNC damaged too (0x5A): the candidate "
        "the byte after a frame starts holds no reading and does not start with 0xA5, so it is dropped without a "
        "rejection", status + damage(bad9, {0: 0xFF}), [ev_frame(status)])

    for s in S:
        d = frame.Decoder()
        got = as_events(d.feed(bytes.fromhex(s["wire"])))
        if got != s["events"] or d.pending() != s["pending"]:
            raise SystemExit(f"make_vectors: {s['name']}: constructed {s['events']} but the decoder gives {got}")
        pending, items = d.reset()
        if as_events(items) != s["after_timeout"] or pending != s["pending"] or d.pending():
            raise SystemExit(f"make_vectors: {s['name']}: constructed {s['after_timeout']} after the timeout but the "
                             f"decoder gives {as_events(items)}")
        if "then" in s and as_events(d.feed(bytes.fromhex(s["then"]["wire"]))) != s["then"]["events"]:
            raise SystemExit(f"make_vectors: {s['name']}: the decoder disagrees with the events after the timeout")
    return S


def random_stream_vectors():
    """Random streams of frames (some with 1 to 3 damaged bytes, some without their parity or cut short) between
    noise, and the events the Python decoder gives for them (read back, not constructed: the C test must agree)."""
    rng = random.Random(505)
    out = []
    for k in range(200):
        wire = bytearray()
        for _ in range(rng.randrange(1, 5)):
            wire += bytes(rng.randrange(256) for _ in range(rng.choice((0, 0, 1, 3))))
            t = rng.choice([int(m) for m in MsgType] + [0x33])
            t |= 0x80 if rng.randrange(2) and t != 0x33 else 0
            n = frame.implied_len(t)
            b = bytearray(frame.encode(rng.randrange(256), t, bytes(rng.randrange(256) for _ in range(
                n if n >= 0 else rng.randrange(59)))))
            for _ in range(rng.choice((0, 1, 1, 1, 2, 3))):
                b[rng.randrange(1, len(b))] ^= rng.randrange(1, 256)
            cut = rng.choice((0, 0, 0, 2, 2, 5))
            wire += b[:len(b) - cut]
        d = frame.Decoder()
        events = d.feed(wire)
        pending, after = d.reset()
        if d.pending():
            raise SystemExit(f"make_vectors: random {k}: the decoder is still pending after the timeout")
        out.append({"name": f"random {k}", "wire": bytes(wire).hex(), "events": as_events(events),
                    "pending": pending, "after_timeout": as_events(after)})
    return out


def bad_payload_vectors():
    """Frames that pass the CRC but whose payload length is wrong for their TYPE: unpack must refuse them."""
    out = []
    for t in MsgType:
        if t == MsgType.NAK:
            continue
        for kind, good, ftype in (("request", messages.request_len(t), int(t)),
                                  ("response", messages.response_len(t), int(t) | 0x80)):
            for n in sorted({good - 1, good + 1, 58} - {-1, good}):
                payload = bytes([0xA5]) * n
                out.append({"name": f"{t.name} {kind} with {n} bytes", "kind": kind, "msg": int(t), "type": ftype,
                            "payload": payload.hex(), "wire": frame.encode(3, ftype, payload).hex(),
                            "status": "BAD_LENGTH"})
    return out


def window_vectors():
    """Requests fed in order to a receiver's window (rbx1_window.c, window.py). Every expected verdict is written by
    hand here; answer_of: a duplicate is answered with the answer recorded for that step; last_seq: what a HELLO
    that starts a session reports; released: after a new request, the held requests that run behind it, in order
    (each named by the step that first held it; its answer is recorded as that step index); dropped: after an ESTOP,
    the SEQs of the held requests it drops (never run)."""
    def req(seq, t=MsgType.STATUS, **fields):
        payload = messages.pack_request(t, **fields) if int(t) in [int(m) for m in MsgType] and t != MsgType.NAK \
            else b""
        return frame.encode(seq, t, payload).hex()

    def move(seq, x):
        return req(seq, MsgType.MOVE, target=[x, 0, 0, 0, 0, 0], duration_ms=0)

    hello = lambda seq: req(seq, MsgType.HELLO, proto_version=PROTO_VERSION)  # noqa: E731
    V = []

    def add(name, description, steps):
        keys = ("wire", "verdict", "answer_of", "last_seq")
        out = []
        for s in steps:
            extra = s[-1] if isinstance(s[-1], dict) else {}
            out.append({**dict(zip(keys, s[:-1] if isinstance(s[-1], dict) else s)), **extra})
        V.append({"name": name, "description": description, "steps": out})

    add("power_up", "after power-up the first request is in order whatever its SEQ; then strictly SEQ + 1; a request "
        "ahead of the next one is held and runs behind it; one behind the window is the past",
        [(req(200), "new"), (req(201), "new"), (req(201), "duplicate", 1), (move(203, 5), "held"),
         (move(199, 5), "old"), (req(200), "duplicate", 0), (req(202), "new", {"released": [3]}),
         (move(203, 5), "duplicate", 3)])
    add("window_of_8", "the last 8 requests are remembered; older ones are refused, never run again",
        [(move(10 + i, i), "new") for i in range(10)] +
        [(move(12, 2), "duplicate", 2), (move(11, 1), "old"), (move(10, 0), "old"), (move(19, 9), "duplicate", 9),
         (move(20, 10), "new"), (move(12, 2), "old"), (move(13, 3), "duplicate", 3)])
    add("seq_wraps", "SEQ wraps at 256; 1..7 ahead of the expected SEQ is held, 8..127 ahead a gap, 128..255 ahead "
        "the past",
        [(req(250 + i if i < 6 else i - 6), "new") for i in range(9)] +
        [(req(254), "duplicate", 4), (req(1), "duplicate", 7), (req(4), "held"), (req(10), "held"), (req(11), "gap"),
         (req(130), "gap"), (req(131), "old"), (req(3), "new", {"released": [11]}), (req(5), "new")])
    add("hold_and_fill", "requests 1..7 ahead of a missing one are held (not run) and answered HELD, a copy of a held "
        "one HELD again (kept once), other bytes at a held SEQ refused; the missing one runs, then the held ones in "
        "SEQ order, each once; their copies are then answered from memory",
        [(req(10), "new"), (move(12, 2), "held"), (move(13, 3), "held"), (move(12, 2), "held"), (move(12, 9), "old"),
         (move(19, 9), "gap"), (move(18, 8), "held"), (move(11, 1), "new", {"released": [1, 2]}),
         (move(12, 2), "duplicate", 1), (move(13, 3), "duplicate", 2), (move(14, 4), "new"),
         (move(15, 5), "new"), (move(16, 6), "new"), (move(17, 7), "new", {"released": [6]}),
         (move(18, 8), "duplicate", 6), (move(19, 9), "new")])
    add("held_in_any_order", "held requests arriving in any order run in SEQ order as each gap before them is filled",
        [(req(0), "new"), (move(7, 7), "held"), (move(5, 5), "held"), (move(3, 3), "held"), (move(2, 2), "held"),
         (move(1, 1), "new", {"released": [4, 3]}), (move(4, 4), "new", {"released": [2]}),
         (move(6, 6), "new", {"released": [1]}), (move(8, 8), "new")])
    add("window_full_of_held", "a whole window behind one missing request: 7 held, the 8th ahead is a gap; the "
        "missing one releases all 7",
        [(req(100), "new")] + [(move(102 + i, i), "held") for i in range(7)] + [(move(109, 7), "gap"),
         (move(101, 9), "new", {"released": list(range(1, 8))}), (move(102, 0), "duplicate", 1),
         (move(109, 7), "new")])
    add("held_then_hello", "a HELLO that starts a session forgets the held requests: none runs",
        [(req(20), "new"), (move(22, 2), "held"), (move(23, 3), "held"), (hello(20), "new", None, 20),
         (req(21), "new", {"released": []}), (move(22, 2), "new"), (move(23, 3), "new")])
    add("held_then_estop", "an ESTOP drops the held requests (never run; the firmware NAKs each SEQ_GAP after the "
        "ESTOP's answer); sent again, they are held again and run once the gap is filled",
        [(req(30), "new"), (move(33, 3), "held"), (move(32, 2), "held"),
         (req(31, MsgType.ESTOP), "bypass", {"dropped": [32, 33]}), (req(31, MsgType.ESTOP), "bypass", {"dropped": []}),
         (move(32, 2), "held"), (req(31), "new", {"released": [5]}), (move(33, 3), "new")])
    add("held_then_stop", "a STOP takes its place in the order like any request: held ahead of a gap, it runs after "
        "the requests before it and before those after it; requests held behind a STOP that fills a gap run after it",
        [(req(40), "new"), (move(42, 2), "held"), (req(43, MsgType.STOP), "held"), (move(44, 4), "held"),
         (move(41, 1), "new", {"released": [1, 2, 3]}), (req(45), "new"), (move(47, 7), "held"),
         (req(46, MsgType.STOP), "new", {"released": [6]})])
    add("hello_restarts", "a HELLO that is not a duplicate forgets the window and its SEQ sets the order",
        [(req(5), "new"), (req(6), "new"), (hello(100), "new", None, 6), (req(6), "old"), (hello(100), "duplicate", 2),
         (req(101), "new"), (hello(50), "new", None, 101), (req(51), "new"), (req(30), "old"), (req(53), "held"),
         (req(60), "gap")])
    add("hello_of_a_new_host", "a HELLO with the bytes of a remembered one that other requests followed is a new host "
        "starting at the same SEQ (a tool run twice), not a retransmission: a new session, and its requests run",
        [(hello(0), "new", None, 255), (req(1), "new"), (hello(0), "new", None, 1), (req(1), "new"),
         (hello(0), "new", None, 1), (hello(0), "duplicate", 4), (req(1), "new")])
    add("estop_bypasses", "ESTOP (any payload length, any SEQ) is executed every time and takes no place in the order",
        [(req(9), "new"), (req(77, MsgType.ESTOP), "bypass"), (req(10, MsgType.ESTOP), "bypass"),
         (frame.encode(10, MsgType.ESTOP, b"\x01").hex(), "bypass"), (req(10), "new"), (req(10), "duplicate", 4)])
    add("same_seq_other_bytes", "a used SEQ with other bytes is not a retransmission: refused",
        [(move(30, 1), "new"), (move(30, 2), "old"), (move(30, 1), "duplicate", 0)])
    crc = lambda wire: int.from_bytes(bytes.fromhex(wire)[-6:-2], "little")  # noqa: E731
    x = next(x for x in range(2, 1 << 20) if (crc(move(31, x)) ^ crc(move(31, 1))) & 0xFFFF == 0)  # high halves differ
    add("crc_high_half_tells", f"two MOVEs with one SEQ whose CRC-32s differ in the high 16 bits alone (targets 1 and "
        f"{x}): the window compares all 32 bits, so the second is a used SEQ with other bytes, not a duplicate",
        [(move(31, 1), "new"), (move(31, x), "old"), (move(31, 1), "duplicate", 0)])
    add("unknown_type_no_place", "a frame of no request type (unknown id, NAK, a response) is NAKed UNKNOWN_TYPE "
        "whatever its SEQ and takes no place in the order: its SEQ stays the next one, nothing is remembered",
        [(req(40), "new"), (frame.encode(41, 0x33, b"").hex(), "unknown"), (frame.encode(41, 0x33, b"").hex(), "unknown"),
         (frame.encode(41, MsgType.NAK, b"\x01").hex(), "unknown"), (frame.encode(41, 0x82, bytes(40)).hex(), "unknown"),
         (frame.encode(45, 0x33, b"").hex(), "unknown"), (frame.encode(30, 0x33, b"").hex(), "unknown"),
         (req(41), "new"), (req(41), "duplicate", 7), (frame.encode(42, 0x33, b"").hex(), "unknown"),
         (req(42), "new"), (hello(90), "new", None, 42), (frame.encode(91, 0x40, b"").hex(), "unknown"),
         (req(91), "new"), (req(93), "held")])
    add("probe_keeps_the_hold", "a host's probe (PROTOCOL.md \"Probe\": TYPE 0x7F, no payload, the SEQ before the "
        "oldest unanswered request) while requests are held: NAKed UNKNOWN_TYPE, nothing held is dropped or run, the "
        "order does not move; the gap filled runs the held ones in order, the probe again changes nothing",
        [(move(60, 0), "new"), (move(62, 2), "held"), (move(63, 3), "held"),
         (frame.encode(60, MsgType.NAK, b"").hex(), "unknown"), (move(62, 2), "held"),
         (frame.encode(60, MsgType.NAK, b"").hex(), "unknown"), (move(61, 1), "new", {"released": [1, 2]}),
         (frame.encode(60, MsgType.NAK, b"").hex(), "unknown"), (move(64, 4), "new"), (move(62, 2), "duplicate", 1)])
    # The Python window agrees (the C test checks the same file).
    from rbx1proto.window import Window, replay
    for v in V:
        for i, (st, (verdict, answer, last, released, dropped)) in enumerate(zip(v["steps"], replay(Window(), v["steps"]))):
            assert verdict == st["verdict"], (v["name"], i, verdict, st)
            if verdict == "duplicate":
                assert answer == st["answer_of"], (v["name"], i, answer)
            if st.get("last_seq") is not None:
                assert last == st["last_seq"], (v["name"], i, last)
            assert released == st.get("released", []), (v["name"], i, released)
            assert dropped == st.get("dropped", []), (v["name"], i, dropped)
    return V


def gf_mul(a, b):
    """a * b in GF(2^8) mod 0x11D, bit by bit (independent of frame.py's shift-and-XOR encoder)."""
    r = 0
    while b:
        if b & 1:
            r ^= a
        a, b = (a << 1) ^ (0x11D if a & 0x80 else 0), b >> 1
    return r


def evaluate(code, x):
    """The codeword as a polynomial (first byte the highest power) at x."""
    r = 0
    for c in code:
        r = gf_mul(r, x) ^ c
    return r


def fec_vectors():
    """Parity of sample data, and what locating finds in sample codewords (at: the damaged byte's index, -1 no error,
    -2 no single damaged byte explains the syndromes; error: the XOR that restores it). Written by construction and
    checked against frame.py (the C and Python tests check both)."""
    move = frame.encode(7, MsgType.MOVE, messages.pack_request(MsgType.MOVE, target=[1, 2, 3, 4, 5, 6], duration_ms=0))
    maxf = frame.encode(1, 0x55, bytes(range(58)))
    out = []
    for name, data in (("empty", b""), ("one zero", b"\x00"), ("check string", b"123456789"), ("ff x 10", b"\xff" * 10),
                       ("MOVE LEN..CRC", move[1:-2]), ("68-byte frame LEN..CRC", maxf[1:-2])):
        parity = frame.fec_parity(data)
        code = data + parity
        assert evaluate(code, 1) == 0 and evaluate(code, 2) == 0, name  # divisible by (x + 1)(x + 2)
        out.append({"name": f"parity of {name}", "data": data.hex(), "parity": parity.hex()})

    def locate(name, code, at, error=0):
        found = frame.fec_locate(code)
        assert found == (None if at == -1 else -1 if at == -2 else (at, error)), (name, found)
        out.append({"name": name, "code": code.hex(), "at": at, "error": error})

    def hit(code, errors):
        c = bytearray(code)
        for i, x in errors.items():
            c[i] ^= x
        return bytes(c)

    mc, fc = move[1:], maxf[1:]  # a 35-byte and a 67-byte codeword
    locate("MOVE codeword intact", mc, -1)
    for i, x in ((0, 0x1A ^ 0x0C), (1, 0x01), (17, 0xFF), (32, 0xA5), (33, 0x80), (34, 0x7F)):
        locate(f"MOVE codeword, byte {i} damaged", hit(mc, {i: x}), i, x)
    locate("67-byte codeword intact", fc, -1)
    for i in (0, 33, 65, 66):
        locate(f"67-byte codeword, byte {i} damaged", hit(fc, {i: 0x5A}), i, 0x5A)
    locate("MOVE codeword, one error value twice (S1 = 0)", hit(mc, {3: 0x44, 9: 0x44}), -2)
    far = next(x for x in range(1, 256) if frame.fec_locate(hit(mc, {3: x, 9: 0x81})) == -1
               and evaluate(hit(mc, {3: x, 9: 0x81}), 1) and evaluate(hit(mc, {3: x, 9: 0x81}), 2))
    locate("MOVE codeword, two damaged bytes pointing beyond its start", hit(mc, {3: far, 9: 0x81}), -2)
    x = next(x for x in range(1, 256) if isinstance(frame.fec_locate(hit(mc, {3: x, 9: 0x81})), tuple))
    at, error = frame.fec_locate(hit(mc, {3: x, 9: 0x81}))
    assert at not in (3, 9)
    locate("MOVE codeword, two damaged bytes that read as one elsewhere", hit(mc, {3: x, 9: 0x81}), at, error)
    return out


def crc_vectors():
    sent, got, _ = crc16_collision()  # two bodies with one CRC-16 and two CRC-32s
    return [{"data": b"123456789".hex(), "crc": 0xCBF43926}, {"data": "", "crc": 0},
            {"data": "00", "crc": frame.crc32(b"\x00")}, {"data": "a5" * 10, "crc": frame.crc32(b"\xa5" * 10)},
            {"data": sent[1:-6].hex(), "crc": frame.crc32(sent[1:-6])},
            {"data": got[1:-6].hex(), "crc": frame.crc32(got[1:-6])}]


def main():
    assert frame.crc32(b"123456789") == 0xCBF43926
    docs = {
        "messages.json": {"description": "every message type's request and response (and NAKs): fields, payload and "
                          "wire bytes in hex; crc is the frame's CRC", "vectors": message_vectors()},
        "streams.json": {"description": "byte streams and the decoder events they produce, in order, for any "
                         "chunking; pending: a partial frame remains at the end; after_timeout: the events of the inter-byte "
                         "timeout that follows (its rescan)", "vectors": stream_vectors()},
        "bad_payloads.json": {"description": "CRC-valid frames whose payload length is wrong for their type: "
                              "unpack refuses them (BAD_LENGTH; the firmware answers a request like this with "
                              "status BAD_LENGTH, except ESTOP, which stops the arm whatever its length)", "vectors": bad_payload_vectors()},
        "random_streams.json": {"description": "random streams of frames (some with 1 to 3 damaged bytes, some "
                                "without their parity or cut short) between noise, with the events the Python decoder "
                                "gives, after_timeout as in streams.json: read back from it, so that the C decoder is "
                                "checked against the Python one in any chunking", "vectors": random_stream_vectors()},
        "fec.json": {"description": "Reed-Solomon parity (GF(2^8), 0x11D, generator (x + 1)(x + 2)): parity "
                     "vectors give data and its 2 parity bytes; locate vectors give a codeword (data then parity) and "
                     "what locating finds: at = index of the one damaged byte and error = the XOR that restores it, "
                     "at -1 = no error, -2 = no single damaged byte explains the syndromes (error 0)",
                     "vectors": fec_vectors()},
        "crc.json": {"description": "CRC-32/ISO-HDLC of data (hex); the last two have the same CRC-16/CCITT-FALSE "
                     "(vector crc16_collision in streams.json)", "vectors": crc_vectors()},
        "window.json": {"description": "requests fed in order to a receiver's window, with the expected verdict "
                        "(new, duplicate, held, gap, old, bypass, unknown); a new request's answer is recorded as its step "
                        "index, answer_of names the step whose answer a duplicate gets, last_seq what a "
                        "session-starting HELLO reports, released the steps whose held requests run after a new one "
                        "(in order; each answer recorded as that step's index), dropped the SEQs an ESTOP drops from "
                        "the hold", "vectors": window_vectors()},
    }
    for name, doc in docs.items():
        with open(os.path.join(HERE, name), "w") as f:
            json.dump(doc, f, indent=1)
            f.write("\n")


if __name__ == "__main__":
    main()
