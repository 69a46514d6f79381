"""test_sender.py - the Python window sender (rbx1proto/sender.py) reproduces every shared sender trace step by step
(the C++ sender's test, host/link/window_sender_test.cpp, reads the same file)."""
import pytest
from conftest import load_vectors

from rbx1proto import frame, messages
from rbx1proto.messages import MsgType, Status
from rbx1proto.sender import Sender

TRACES = load_vectors("sender_traces.json")


def received(ev):
    """A trace's event as the frame the sender is told of (as make_sender_traces.py builds it)."""
    if ev[0] == "R":
        wire = frame.encode(ev[1], ev[2] | 0x80, bytes(messages.response_len(MsgType(ev[2]))))
    else:
        wire = frame.encode(ev[1], MsgType.NAK, messages.pack_nak(Status[ev[2]]))
    (f,) = frame.Decoder().feed(wire)
    return f


def sender(v):
    types = [MsgType(t) for t in v["types"]]
    seqs = [(v["first_seq"] + i) & 0xFF for i in range(len(types))]
    # Frame sizes as on the wire: the line model's deadlines depend on them.
    sizes = [frame.OVERHEAD + max(0, messages.request_len(t)) for t in types]
    return Sender(types, seqs, sizes, v["window"], ahead=v["ahead"], timeout=v["timeout_ms"] / 1000,
                  baudrate=v["baud"], retries=v["retries"])


@pytest.mark.parametrize("v", TRACES, ids=[v["name"] for v in TRACES])
def test_sender_reproduces_trace(v):
    s = sender(v)
    first, *rest = v["steps"]
    assert [[w.frames, w.probe] for w in s.start(first["at_us"] / 1e6)] == first["out"]
    for k, step in enumerate(rest, 1):
        assert not s.finished, f"step {k}: finished early"
        for ev in step["in"]:
            s.feed(received(ev))
        out = s.step(step["at_us"] / 1e6)
        assert [[w.frames, w.probe] for w in out] == step["out"], f"step {k} at {step['at_us']} us"
        if "deadline_us" in step:
            assert abs(s.deadline() * 1e6 - step["deadline_us"]) <= 3, f"step {k}"
    assert s.finished
    result = "ok" if s.error is None else ("seq_old" if "SEQ_OLD" in s.error else "link_down")
    assert result == v["result"]
    assert [r is not None for r in s.results] == v["answered"]
    c = s.counters
    assert (c.retransmissions, c.timeouts, c.probes) == (v["retransmissions"], v["timeouts"], v["probes"])


def test_traces_cover_every_kind_of_event():
    """The traces exercise answers, each NAK the sender acts on, probes, timeouts, link down and SEQ_OLD."""
    kinds = {ev[2] if ev[0] == "N" else "R" for v in TRACES for st in v["steps"] for ev in st["in"]}
    assert {"R", "HELD", "BAD_CRC", "UNKNOWN_TYPE", "SEQ_GAP", "SEQ_OLD"} <= kinds
    assert {v["result"] for v in TRACES} == {"ok", "link_down", "seq_old"}
    assert any(v["timeouts"] for v in TRACES) and any(w[1] is not None for v in TRACES for st in v["steps"]
                                                      for w in st["out"])
