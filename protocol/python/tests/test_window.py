"""test_window.py - the Python receiver window against the shared window vectors (the C test reads the same file)."""
import pytest
from conftest import load_vectors

from rbx1proto import frame
from rbx1proto.window import WINDOW, Window

VECTORS = load_vectors("window.json")


@pytest.mark.parametrize("v", VECTORS, ids=[v["name"] for v in VECTORS])
def test_window_vectors(v):
    w = Window()
    for i, st in enumerate(v["steps"]):
        (f,) = frame.Decoder().feed(bytes.fromhex(st["wire"]))
        verdict, answer, last = w.accept(f)
        assert verdict == st["verdict"], f"step {i}"
        if verdict == "duplicate":
            assert answer == st["answer_of"], f"step {i}"
        if st.get("last_seq") is not None:
            assert last == st["last_seq"], f"step {i}"
        if verdict == "new":
            w.record(f.seq, f.crc, i)


def test_window_size_matches_the_c_library():
    import os
    src = os.path.join(os.path.dirname(__file__), "..", "..", "src", "rbx1_window.h")
    with open(src) as fh:
        assert f"#define RBX1_WINDOW {WINDOW}\n" in fh.read()
