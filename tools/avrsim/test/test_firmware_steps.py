"""test_firmware_steps.py - the real firmware (build/firmware/rbx1.elf) under rbx1-avrsim: the STEP pulses counted on
the pins equal the commanded multi-joint targets exactly, and an e-stop input stops the pulses within 40 cycles.
Env: AVRSIM, RBX1_FIRMWARE_ELF, RBX1_SOURCE_DIR."""
import json
import os
import subprocess
import sys
import time

import pytest

SRC = os.environ.get("RBX1_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", ".."))
sys.path.insert(0, os.path.join(SRC, "protocol", "python"))
from rbx1proto.link import Link  # noqa: E402
from rbx1proto.messages import Fault, MsgType, State, Status  # noqa: E402

AVRSIM = os.environ.get("AVRSIM", os.path.join(SRC, "build", "bin", "rbx1-avrsim"))
ELF = os.environ.get("RBX1_FIRMWARE_ELF", os.path.join(SRC, "build", "firmware", "rbx1.elf"))


@pytest.fixture
def board(tmp_path):
    assert os.path.exists(ELF), f"{ELF} missing: run tools/build-firmware"
    out = tmp_path / "avrsim.json"
    fifo = tmp_path / "control.fifo"
    proc = subprocess.Popen([AVRSIM, "--elf", ELF, "--json", str(out), "--control", str(fifo), "--max-seconds", "60"],
                            stdout=subprocess.PIPE, text=True)
    link = Link(proc.stdout.readline().strip())
    link.hello()
    ctl = open(os.open(fifo, os.O_WRONLY), "w")

    def control(line):
        ctl.write(line + "\n")
        ctl.flush()

    def finish():
        control("quit")
        assert proc.wait(timeout=10) == 0
        return json.loads(out.read_text())

    yield link, control, finish
    link.close()
    if proc.poll() is None:
        proc.kill()
        proc.wait()


def ok(link, msg_type, **fields):
    r = link.request(msg_type, **fields)
    assert r["status"] == Status.OK, (msg_type, fields, r)
    return r


def wait_idle(link, timeout=10.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        s = ok(link, MsgType.STATUS)
        if s["state"] == State.IDLE:
            return s
        time.sleep(0.02)
    raise AssertionError(f"not IDLE after {timeout} s: {s}")


def test_pulses_equal_commanded_targets(board):
    link, _, finish = board
    ok(link, MsgType.ENABLE, enable=1)
    ok(link, MsgType.SET_POSITION, position=[0] * 6)
    moves = [[900, -700, 500, -300, 250, -120], [400, -100, 820, 0, -250, 60]]
    for t in moves:
        ok(link, MsgType.MOVE, target=t, duration_ms=0)
    s = wait_idle(link)
    assert s["position"] == moves[-1]
    assert s["moves_done"] == 2
    # The firmware runs its 500 ms watchdog: simavr must model it without spurious resets (a reset would also
    # have cleared the homed bits and the position).
    time.sleep(0.7)
    s = ok(link, MsgType.STATUS)
    assert not s["faults"] & Fault.WATCHDOG_RESET and s["homed"] == 0x3F, s
    out = finish()
    assert out["steps"] == moves[-1]  # net signed pulses per joint, DIR read on every STEP edge
    assert out["pulses"] == [abs(a) + abs(b - a) for a, b in zip(*moves)]
    isr = out["isr"]
    assert isr["vector"] is not None and isr["step_calls"] > 0
    assert isr["pulses"] == sum(out["pulses"])  # every pulse came from the step interrupt
    assert 0 < isr["mean_cycles"] <= isr["max_cycles"]


def test_estop_input_stops_pulses(board):
    link, control, finish = board
    ok(link, MsgType.ENABLE, enable=1)
    ok(link, MsgType.SET_POSITION, position=[0] * 6)
    ok(link, MsgType.MOVE, target=[3000, 3000, 3000, 0, 0, 0], duration_ms=0)
    end = time.monotonic() + 3
    while ok(link, MsgType.STATUS)["position"][0] < 200:
        assert time.monotonic() < end, "the move did not start"
        time.sleep(0.01)
    control("estop 1")
    time.sleep(0.2)
    s = ok(link, MsgType.STATUS)
    assert s["state"] == State.FAULT and s["faults"] & Fault.ESTOP_INPUT
    out = finish()
    assert out["estop_events"] == 1
    assert out["steps"][:3] == s["position"][:3]  # the firmware's count and the pins agree after the stop
    assert out["pulses"][0] < 3000
    latency = out["estop_latency_cycles"]
    # The input is sampled right before the pulses: at most the few cycles from that sample to the last STEP write
    # (tools/avrsim/test/test_timing.py measures the worst case over random phases).
    assert latency is not None and 0 <= latency <= 40, latency
