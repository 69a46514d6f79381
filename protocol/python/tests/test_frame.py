"""test_frame.py - Python framing (CRC, encode, decoder) against the shared vectors, in any chunking."""
import binascii
import random

import pytest
from conftest import load_vectors

from rbx1proto import frame
from rbx1proto.messages import Status

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
    assert frame.OVERHEAD == 8
    assert len(frame.encode(0, 2)) == 8
    move = next(v for v in MESSAGES if v["name"] == "MOVE request")
    assert len(bytes.fromhex(move["wire"])) == 34


@pytest.mark.parametrize("v", MESSAGES, ids=lambda v: v["name"])
def test_encode_message_vectors(v):
    assert frame.encode(v["seq"], v["type"], bytes.fromhex(v["payload"])).hex() == v["wire"]


def test_encode_rejects_oversize():
    assert len(frame.encode(1, 2, bytes(58))) == 66
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
    move, resp, nak = wire[:34], wire[34:44], wire[44:]
    for part in (move, resp, nak):
        assert part.hex(" ") in doc
    for part in (move, resp):
        assert "CRC 0x%08x (sent %s)" % (frame.crc32(part[1:-4]), part[-4:].hex(" ")) in doc
    assert [type(e) for e in frame.Decoder().feed(wire)] == [frame.Frame] * 3


def test_crc16_collision_is_rejected():
    """Vector crc16_collision: a MOVE whose line damage leaves version 3's CRC-16 intact. The CRC-32 must reject it
    (a decoder still on CRC-16 would deliver the damaged MOVE)."""
    v = next(v for v in STREAMS if v["name"] == "crc16_collision")
    got = bytes.fromhex(v["wire"])
    crcs = load_vectors("crc.json")[-2:]  # the bodies sent and received
    a, b = (bytes.fromhex(c["data"]) for c in crcs)
    assert b == got[1:-4] and a != b and len(a) == len(b)
    assert binascii.crc_hqx(a, 0xFFFF) == binascii.crc_hqx(b, 0xFFFF)
    assert frame.crc32(a) != frame.crc32(b) and frame.crc32(a) == int.from_bytes(got[-4:], "little")
    assert as_json(frame.Decoder().feed(got)) == [{"reject": {"status": "BAD_CRC", "seq": 7}}]
