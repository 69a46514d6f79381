"""test_frame.py - Python framing (CRC, encode, decoder) against the shared vectors, in any chunking."""
import binascii
import os
import random
import sys

import pytest
from conftest import PROTOCOL_DIR, load_vectors

from rbx1proto import frame
from rbx1proto.messages import Status

sys.path.insert(0, os.path.join(PROTOCOL_DIR, "vectors"))
from make_vectors import evaluate  # noqa: E402  (bit by bit, independent of frame.py's shift-and-XOR)

STREAMS = load_vectors("streams.json")
MESSAGES = load_vectors("messages.json")


def as_json(events):
    return [{"frame": {"seq": e.seq, "type": e.type, "payload": e.payload.hex(), "crc": e.crc}}
            if isinstance(e, frame.Frame) else {"reject": {"status": Status(e.status).name, "seq": e.seq}}
            for e in events]


def feed_chunked(data, chunks):
    d = frame.Decoder()
    out, pos, k = [], 0, 0
    while pos < len(data):
        n = chunks[k % len(chunks)]
        out += d.feed(data[pos:pos + n])
        pos, k = pos + n, k + 1
    return out, d.pending(), d


def test_crc_check_value():
    assert frame.crc32(b"123456789") == 0xCBF43926


@pytest.mark.parametrize("v", load_vectors("crc.json"), ids=lambda v: v["data"][:12] or "empty")
def test_crc_vectors(v):
    assert frame.crc32(bytes.fromhex(v["data"])) == v["crc"]


def test_budget_overhead_and_move_size():
    assert frame.OVERHEAD == 10 and frame.FEC_BYTES == 2 and frame.MAX_FRAME == 68
    assert len(frame.encode(0, 2)) == 10
    move = next(v for v in MESSAGES if v["name"] == "MOVE request")
    assert len(bytes.fromhex(move["wire"])) == 36


@pytest.mark.parametrize("v", MESSAGES, ids=lambda v: v["name"])
def test_encode_message_vectors(v):
    assert frame.encode(v["seq"], v["type"], bytes.fromhex(v["payload"])).hex() == v["wire"]


def test_encode_rejects_oversize():
    assert len(frame.encode(1, 2, bytes(58))) == 68
    with pytest.raises(ValueError):
        frame.encode(1, 2, bytes(59))


@pytest.mark.parametrize("chunks", [[1 << 20], [1], [2], [3, 1, 7], [5, 64, 1], [63]])
@pytest.mark.parametrize("v", STREAMS, ids=lambda v: v["name"])
def test_stream_vectors(v, chunks):
    events, pending, d = feed_chunked(bytes.fromhex(v["wire"]), chunks)
    assert as_json(events) == v["events"]
    assert pending == v["pending"]
    was_pending, items = d.reset()  # the inter-byte timeout that follows
    assert was_pending == v["pending"] and not d.pending()
    assert as_json(items) == v["after_timeout"]
    if "then" in v:  # bytes that arrive after the timeout
        assert as_json(d.feed(bytes.fromhex(v["then"]["wire"]))) == v["then"]["events"]


@pytest.mark.parametrize("chunks", [[1 << 20], [1], [3, 1, 7]])
def test_random_damaged_streams(chunks):
    """random_streams.json: the events this decoder gave when the vectors were written (the C test checks the same)."""
    for v in load_vectors("random_streams.json"):
        events, pending, d = feed_chunked(bytes.fromhex(v["wire"]), chunks)
        assert as_json(events) == v["events"], v["name"]
        assert pending == v["pending"]
        assert as_json(d.reset()[1]) == v["after_timeout"], v["name"]
        assert not d.pending()


def test_timeout_rescan_finds_the_swallowed_frame():
    trunc = next(v for v in STREAMS if v["name"] == "truncated_swallows_short_frame")
    d = frame.Decoder()
    assert d.feed(bytes.fromhex(trunc["wire"])) == []
    assert d.pending()
    pending, items = d.reset()
    assert pending is True and [(f.type, f.payload) for f in items] == [(2, b"")]
    assert d.reset() == (False, [])
    (f,) = d.feed(frame.encode(4, 2))
    assert (f.seq, f.type, f.payload) == (4, 2, b"")


def test_random_frames_in_noise_all_found():
    rng = random.Random(99)
    sent, wire = [], bytearray()
    for i in range(200):
        wire += bytes(rng.choice([b for b in range(256) if b != frame.SYNC]) for _ in range(rng.randrange(5)))
        payload = bytes(rng.randrange(256) for _ in range(rng.randrange(59)))
        sent.append((i, payload))
        wire += frame.encode(i, rng.randrange(256), payload)
    events, pending, _ = feed_chunked(bytes(wire), [1, 9, 2, 33])
    assert [(e.seq, e.payload) for e in events] == sent
    assert not pending


def test_protocol_md_example_is_the_vector():
    """The hex example in PROTOCOL.md is exactly what the implementation produces."""
    import os
    from conftest import PROTOCOL_DIR
    with open(os.path.join(PROTOCOL_DIR, "PROTOCOL.md")) as f:
        doc = f.read()
    v = next(v for v in STREAMS if v["name"] == "protocol_md_example")
    wire = bytes.fromhex(v["wire"])
    move, resp, nak = wire[:36], wire[36:48], wire[48:]
    assert len(nak) == 11
    for part in (move, resp, nak):
        assert part.hex(" ") in doc
    for part in (move, resp):
        assert "CRC 0x%08x (sent %s)" % (frame.crc32(part[1:-6]), part[-6:-2].hex(" ")) in doc
        assert "parity " + part[-2:].hex(" ") in doc.replace("\n", " ")
    assert [type(e) for e in frame.Decoder().feed(wire)] == [frame.Frame] * 3


def test_crc16_collision_is_rejected():
    """Vector crc16_collision: a MOVE whose line damage leaves version 3's CRC-16 intact. The CRC-32 must reject it
    (a decoder still on CRC-16 would deliver the damaged MOVE)."""
    v = next(v for v in STREAMS if v["name"] == "crc16_collision")
    got = bytes.fromhex(v["wire"])
    crcs = load_vectors("crc.json")[-2:]  # the bodies sent and received
    a, b = (bytes.fromhex(c["data"]) for c in crcs)
    assert b == got[1:-6] and a != b and len(a) == len(b)
    assert binascii.crc_hqx(a, 0xFFFF) == binascii.crc_hqx(b, 0xFFFF)
    assert frame.crc32(a) != frame.crc32(b) and frame.crc32(a) == int.from_bytes(got[-6:-2], "little")
    assert as_json(frame.Decoder().feed(got)) == [{"reject": {"status": "BAD_CRC", "seq": 7}}]


# ---- Version 5: Reed-Solomon parity (fec_parity, fec_locate) and the decoder's corrected readings ----

FEC = load_vectors("fec.json")


def move_frame():
    from rbx1proto import messages
    return frame.encode(7, messages.MsgType.MOVE, messages.pack_request(
        messages.MsgType.MOVE, target=[1000, -2000, 3000, -4000, 5000, 0], duration_ms=1500))


def event(b):
    """The Frame an intact wire frame decodes to."""
    n = b[1]
    return frame.Frame(b[2], b[3], bytes(b[4:4 + n]), int.from_bytes(b[4 + n:8 + n], "little"))


@pytest.mark.parametrize("v", [v for v in FEC if "parity" in v], ids=lambda v: v["name"])
def test_fec_parity_vectors(v):
    assert frame.fec_parity(bytes.fromhex(v["data"])).hex() == v["parity"]


@pytest.mark.parametrize("v", [v for v in FEC if "code" in v], ids=lambda v: v["name"])
def test_fec_locate_vectors(v):
    want = None if v["at"] == -1 else -1 if v["at"] == -2 else (v["at"], v["error"])
    assert frame.fec_locate(bytes.fromhex(v["code"])) == want


def test_fec_vectors_cover_each_outcome():
    ats = [v["at"] for v in FEC if "code" in v]
    assert -1 in ats and -2 in ats and sum(a >= 0 for a in ats) >= 5


def test_fec_parity_makes_the_codeword_divisible_by_the_generator():
    rng = random.Random(5)
    for n in range(frame.MAX_FRAME - 2):
        code = bytes(rng.randrange(256) for _ in range(n))
        code += frame.fec_parity(code)
        assert evaluate(code, 1) == 0 and evaluate(code, 2) == 0, n
        assert frame.fec_locate(code) is None


def test_frame_parity_is_the_parity_of_len_to_crc():
    for v in MESSAGES:
        wire = bytes.fromhex(v["wire"])
        assert frame.fec_parity(wire[1:-2]) == wire[-2:], v["name"]


def test_fec_every_single_byte_error_of_a_68_byte_codeword_is_located():
    """Every position with a few error values; every one of the 255 values at a few positions."""
    rng = random.Random(68)
    data = bytes(rng.randrange(256) for _ in range(66))
    code = data + frame.fec_parity(data)
    assert len(code) == 68
    cases = [(i, e) for i in range(68) for e in (0x01, 0x80, 0xA5, 0xFF)]
    cases += [(i, e) for i in (0, 1, 33, 65, 66, 67) for e in range(1, 256)]
    for i, e in cases:
        hit = bytearray(code)
        hit[i] ^= e
        assert frame.fec_locate(hit) == (i, e), (i, e)


def test_every_single_damaged_byte_of_a_move_frame_is_delivered_intact():
    """Each byte after SYNC of a 36-byte MOVE, with every error value: delivered as sent, nothing left pending."""
    move = move_frame()
    assert len(move) == 36
    wrong = []
    for i in range(1, 36):
        for e in range(1, 256):
            hit = bytearray(move)
            hit[i] ^= e
            d = frame.Decoder()
            got = d.feed(hit)
            if got != [event(move)] or d.pending():
                wrong.append((i, e, got))
    assert wrong == []


def test_every_single_damaged_byte_of_a_move_after_another_frame_is_delivered_intact():
    """A STATUS, then a MOVE with any one byte damaged, its SYNC included (the byte right after a delivered frame is
    read as a SYNC whatever its value): both delivered, no rejection, nothing pending."""
    move, status = move_frame(), frame.encode(8, 2)
    wrong = []
    for i in range(36):
        for e in range(1, 256):
            hit = bytearray(move)
            hit[i] ^= e
            d = frame.Decoder()
            got = d.feed(status + hit)
            if got != [event(status), event(move)] or d.pending():
                wrong.append((i, e, got))
    assert wrong == []


def test_random_two_byte_damage_never_delivers_wrong_content():
    from rbx1proto import messages
    rng = random.Random(22)
    intact = rejected = 0
    for _ in range(3000):
        t = rng.randrange(1, 15)
        t, n = (t | 0x80, messages.response_len(t)) if rng.randrange(2) else (t, messages.request_len(t))
        sent = frame.encode(rng.randrange(256), t, bytes(rng.randrange(256) for _ in range(n)))
        i, j = rng.sample(range(1, len(sent)), 2)
        hit = bytearray(sent)
        hit[i] ^= rng.randrange(1, 256)
        hit[j] ^= rng.randrange(1, 256)
        d = frame.Decoder()
        got = d.feed(hit) + d.reset()[1]
        frames = [e for e in got if isinstance(e, frame.Frame)]
        assert all(f == event(sent) for f in frames), (sent.hex(), i, j)
        if frames:
            intact += 1
        else:
            rejected += 1
    assert rejected > 2000 and intact > 0


@pytest.mark.parametrize("at, error, after", [(0, 0, 34), (10, 0x40, 36), (33, 0x01, 36), (34, 0x01, 34),
                                              (1, 26 ^ 12, 36), (1, 26 ^ 40, 36)])
def test_each_reading_delivers_at_its_last_byte(at, error, after):
    """As sent at the last CRC byte (34), corrected at the last parity byte (36), LEN repaired at TYPE's length's."""
    move = move_frame()
    hit = bytearray(move)
    hit[at] ^= error
    d = frame.Decoder()
    when = [k + 1 for k in range(36) if d.feed(hit[k:k + 1])]
    assert when == [after]
    assert not d.pending()
