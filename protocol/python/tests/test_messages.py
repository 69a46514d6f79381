"""test_messages.py - Python message pack/unpack: vectors, round trips through the wire, exact-length checks."""
import pytest
from conftest import load_vectors

from rbx1proto import frame, messages
from rbx1proto.messages import Cap, Fault, Input, Key, MsgType, State, Status

MESSAGES = load_vectors("messages.json")


def codec(v):
    if v["kind"] == "nak":
        return lambda **f: messages.pack_nak(**f), messages.unpack_nak
    t = v["msg"]
    if v["kind"] == "request":
        return (lambda **f: messages.pack_request(t, **f)), (lambda p: messages.unpack_request(t, p))
    return (lambda **f: messages.pack_response(t, **f)), (lambda p: messages.unpack_response(t, p))


@pytest.mark.parametrize("v", MESSAGES, ids=lambda v: v["name"])
def test_vectors_pack_unpack(v):
    pack, unpack = codec(v)
    assert pack(**v["fields"]).hex() == v["payload"]
    assert unpack(bytes.fromhex(v["payload"])) == v["fields"]


@pytest.mark.parametrize("v", MESSAGES, ids=lambda v: v["name"])
def test_round_trip_through_the_wire(v):
    pack, unpack = codec(v)
    wire = frame.encode(v["seq"], v["type"], pack(**v["fields"]))
    (f,) = frame.Decoder().feed(wire)
    assert (f.seq, f.type) == (v["seq"], v["type"])
    assert f.crc == v["crc"]
    assert unpack(f.payload) == v["fields"]


def test_every_type_has_vectors():
    names = {v["name"] for v in MESSAGES}
    for t in MsgType:
        if t != MsgType.NAK:
            assert f"{t.name} request" in names and f"{t.name} response" in names
    assert sum(v["kind"] == "nak" for v in MESSAGES) == 3


@pytest.mark.parametrize("t", [t for t in MsgType if t != MsgType.NAK], ids=lambda t: t.name)
def test_unpack_rejects_wrong_lengths(t):
    for length in range(0, 60):
        for unpack, right in ((messages.unpack_request, messages.request_len(t)),
                              (messages.unpack_response, messages.response_len(t))):
            if length == right:
                assert isinstance(unpack(t, bytes(length)), dict)
            else:
                with pytest.raises(ValueError):
                    unpack(t, bytes(length))


def test_nak_rejects_wrong_lengths():
    assert messages.unpack_nak(b"\x02") == {"reason": 2}
    for p in (b"", b"\x01\x02"):
        with pytest.raises(ValueError):
            messages.unpack_nak(p)


def test_pack_rejects_bad_fields():
    with pytest.raises(ValueError):
        messages.pack_request(MsgType.MOVE, target=[1, 2, 3], duration_ms=0)  # 3 of 6
    with pytest.raises(ValueError):
        messages.pack_request(MsgType.MOVE, target=[0] * 6)  # missing duration_ms
    with pytest.raises(ValueError):
        messages.pack_request(MsgType.HOME, joint_mask=1, extra=2)
    with pytest.raises(ValueError):
        messages.pack_request(MsgType.HOME, joint_mask=256)  # out of u8
    with pytest.raises(ValueError):
        messages.pack_request(0x42)


def test_lengths_and_codes():
    assert messages.request_len(MsgType.MOVE) == 26
    assert messages.response_len(MsgType.STATUS) == 40
    assert messages.request_len(MsgType.NAK) == -1
    assert messages.request_len(0x0F) == -1
    assert [int(t) for t in MsgType] == list(range(1, 15)) + [0x7F]
    assert Status.OK == 0 and Status.EEPROM_ERROR == 13
    assert State.IDLE == 0 and State.FAULT == 4
    assert Fault.ESTOP_INPUT == 1 and Fault.EEPROM_DEFAULTS == 1 << 6
    assert int(messages.FAULTS_LATCHING) == 0x1F
    assert Input.ESTOP == 1 << 6 and Cap.SIMULATED == 1 << 4
    assert Key.SOFT_MIN == 1 and Key.GRIPPER_MAX_US == 18
    assert messages.KEY_INFO[Key.MAX_SPEED] == (False, 1, 20000, 4000)
    assert messages.KEY_INFO[Key.HEARTBEAT_MS] == (True, 100, 60000, 1000)


@pytest.mark.parametrize("v", load_vectors("bad_payloads.json"), ids=lambda v: v["name"])
def test_bad_payload_vectors(v):
    (f,) = frame.Decoder().feed(bytes.fromhex(v["wire"]))  # a valid frame...
    assert f.payload.hex() == v["payload"]
    unpack = messages.unpack_request if v["kind"] == "request" else messages.unpack_response
    with pytest.raises(ValueError):  # ...with the wrong payload length for its type
        unpack(v["msg"], f.payload)
    assert v["status"] == "BAD_LENGTH"
