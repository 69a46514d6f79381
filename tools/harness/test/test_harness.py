"""test_harness.py - the harness itself: its runner counts and reports failures, and its checks catch a device that
breaks the protocol (proxies that renumber every request, so the simulator re-executes retransmissions, or that
NAK a request of the wrong length instead of answering it)."""
import os
import select
import subprocess
import sys
import threading
import tty

import pytest

SRC = os.environ.get("RBX1_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", ".."))
sys.path.insert(0, os.path.join(SRC, "protocol", "python"))
sys.path.insert(0, os.path.join(SRC, "tools", "harness"))
from rbx1proto import frame, messages  # noqa: E402
from rbx1proto.messages import MsgType, Status  # noqa: E402
from rbx1_harness import runner  # noqa: E402
from rbx1_harness.sim import Simulator  # noqa: E402

HARNESS = os.path.join(SRC, "tools", "rbx1-harness")
SIMFW = os.environ.get("RBX1_SIMFW", os.path.join(SRC, "build", "bin", "rbx1-simfw"))


class FakeBoard:
    control = None

    def prepare(self):
        pass


def test_runner_counts_and_reports(monkeypatch):
    monkeypatch.setattr(runner, "CHECKS", [])

    @runner.check("good")
    def good(b):
        runner.expect(True, "never")

    @runner.check("bad")
    def bad(b):
        runner.expect(1 == 2, "one is not two")

    @runner.check("broken")
    def broken(b):
        raise RuntimeError("boom")

    @runner.check("needs_fifo", control=True)
    def needs_fifo(b):
        pass

    lines = []
    assert runner.run(FakeBoard(), out=lines.append) == (1, 2, 1)
    assert lines[0].startswith("PASS  good")
    assert lines[1] == "FAIL  bad: one is not two"
    assert lines[2].startswith("FAIL  broken: RuntimeError: boom")
    assert lines[3].startswith("SKIP  needs_fifo: needs the simulator's control FIFO")
    lines.clear()
    assert runner.run(FakeBoard(), select=["goo"], out=lines.append) == (1, 0, 0)


class RenumberingProxy:
    """A pty in front of a port that gives every request a fresh SEQ (and maps responses back): the device behind
    it can no longer recognise a retransmission."""

    def __init__(self, port):
        self.dev = os.open(port, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.dev)
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self.slave = slave
        self.stop = False
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        host_dec, dev_dec = frame.Decoder(), frame.Decoder()
        seq_map, next_seq = {}, 100
        while not self.stop:
            ready, _, _ = select.select([self.master, self.dev], [], [], 0.05)
            if self.master in ready:
                for f in host_dec.feed(os.read(self.master, 4096)):
                    if isinstance(f, frame.Frame):
                        seq_map[next_seq] = f.seq
                        os.write(self.dev, frame.encode(next_seq, f.type, f.payload))
                        next_seq = (next_seq + 1) & 0xFF
            if self.dev in ready:
                for f in dev_dec.feed(os.read(self.dev, 4096)):
                    if isinstance(f, frame.Frame):
                        os.write(self.master, self.to_host(seq_map.get(f.seq, f.seq), f))

    def to_host(self, seq, f):
        return frame.encode(seq, f.type, f.payload)

    def close(self):
        self.stop = True
        self.thread.join()
        for fd in (self.dev, self.master, self.slave):
            os.close(fd)


class LengthNakProxy(RenumberingProxy):
    """A device that NAKs a wrong payload length (the firmware's old behaviour) instead of the BAD_LENGTH response
    PROTOCOL.md asks for. (Renumbering is harmless for the wrong-length check: nothing is retransmitted.)"""

    def to_host(self, seq, f):
        if f.type & 0x80 and f.payload[:1] == bytes([Status.BAD_LENGTH]):
            return frame.encode(seq, MsgType.NAK, messages.pack_nak(Status.BAD_LENGTH))
        return frame.encode(seq, f.type, f.payload)


@pytest.fixture
def simfw():
    if not os.path.exists(SIMFW):
        pytest.fail(f"{SIMFW} missing: build rbx1-simfw")
    sim = Simulator(SIMFW)
    yield sim
    sim.stop()


def harness(*args):
    r = subprocess.run([sys.executable, HARNESS, *args], capture_output=True, text=True, timeout=60)
    return r.returncode, r.stdout


def test_duplicate_check_passes_on_simfw(simfw):
    code, out = harness("--port", simfw.port, "-k", "duplicate", "-k", "handshake", "-k", "wrong_length")
    assert code == 0, out
    assert out.splitlines()[-1] == "4 passed, 0 failed"  # duplicate_not_reexecuted, window_duplicates_never_rerun


def test_duplicate_check_catches_reexecution(simfw):
    proxy = RenumberingProxy(simfw.port)
    try:
        code, out = harness("--port", proxy.path, "-k", "duplicate", "-k", "move_exact")
    finally:
        proxy.close()
    assert code == 1, out
    assert "FAIL  duplicate_not_reexecuted: " in out, out  # a second queue entry shows in its response or moves_done
    assert "FAIL  window_duplicates_never_rerun: " in out, out  # renumbered duplicates of a window run again
    assert "PASS  move_exact_targets" in out, out  # the proxy is otherwise transparent
    assert out.splitlines()[-1] == "1 passed, 2 failed"


def test_wrong_length_check_rejects_a_nak(simfw):
    proxy = LengthNakProxy(simfw.port)
    try:
        code, out = harness("--port", proxy.path, "-k", "wrong_length", "-k", "move_exact")
    finally:
        proxy.close()
    assert code == 1, out
    assert "FAIL  wrong_length_response: STATUS with 1 payload bytes: NAKed" in out, out
    assert "PASS  move_exact_targets" in out, out
    assert out.splitlines()[-1] == "1 passed, 1 failed"
