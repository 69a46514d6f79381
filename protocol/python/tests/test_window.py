"""test_window.py - the Python receiver window against the shared window vectors (the C test reads the same file)."""
import pytest
from conftest import load_vectors

from rbx1proto import frame
from rbx1proto.window import HELD_MAX, WINDOW, Window, replay

VECTORS = load_vectors("window.json")


@pytest.mark.parametrize("v", VECTORS, ids=[v["name"] for v in VECTORS])
def test_window_vectors(v):
    for i, (st, (verdict, answer, last, released, dropped)) in enumerate(zip(v["steps"], replay(Window(), v["steps"]))):
        assert verdict == st["verdict"], f"step {i}"
        if verdict == "duplicate":
            assert answer == st["answer_of"], f"step {i}"
        if st.get("last_seq") is not None:
            assert last == st["last_seq"], f"step {i}"
        assert released == st.get("released", []), f"step {i}"
        assert dropped == st.get("dropped", []), f"step {i}"


def test_held_frames_keep_their_bytes():
    """A held request runs with its own frame (type, payload), once: release() hands it out a single time."""
    w = Window()
    (a,) = frame.Decoder().feed(frame.encode(5, 0x02, b""))
    (m,) = frame.Decoder().feed(frame.encode(7, 0x04, bytes(range(26))))
    assert w.accept(a)[0] == "new"
    w.record(5, a.crc, "a")
    assert w.accept(m)[0] == "held" and w.accept(m)[0] == "held"
    assert w.release() is None
    w.record(6, 0x1234, "b")
    h = w.release()
    assert (h.seq, h.type, h.payload) == (7, 0x04, bytes(range(26)))
    assert w.release() is None


def test_window_size_matches_the_c_library():
    import os
    src = os.path.join(os.path.dirname(__file__), "..", "..", "src", "rbx1_window.h")
    with open(src) as fh:
        text = fh.read()
    assert f"#define RBX1_WINDOW {WINDOW}\n" in text
    assert HELD_MAX == WINDOW - 1 and "#define RBX1_HELD_MAX (RBX1_WINDOW - 1)\n" in text
