"""test_avrsim.py - rbx1-avrsim against its own test ELF (testfw.c): pty bridge, STEP/DIR counting, ISR timing,
inputs, e-stop latency, EEPROM persistence, reset, watchdog, pacing, exit paths. Env: AVRSIM, AVRSIM_TEST_ELF."""
import json
import os
import signal
import subprocess
import time

import pytest
import serial

AVRSIM = os.environ.get("AVRSIM", "build/bin/rbx1-avrsim")
ELF = os.environ.get("AVRSIM_TEST_ELF", "")
CYCLES_PER_TICK = 1600  # testfw's TIMER1 period: 10 kHz at 16 MHz
STEP_VECTOR = 17        # TIMER1_COMPA on the ATmega2560

@pytest.fixture(autouse=True)
def _test_elf_built():
    # The CMake build makes it with avr-gcc before rbx1-avrsim: missing means a broken build, not a pass.
    if not ELF or not os.path.exists(ELF):
        pytest.fail(f"the avrsim test ELF ({ELF or 'AVRSIM_TEST_ELF unset'}) is not built: run make first")


class Sim:
    def __init__(self, tmp_path, *extra, eeprom=None):
        self.json = tmp_path / "out.json"
        self.fifo = tmp_path / "ctl.fifo"
        args = [AVRSIM, "--elf", ELF, "--json", str(self.json), "--control", str(self.fifo), "--max-seconds", "30"]
        if eeprom:
            args += ["--eeprom", str(eeprom)]
        self.proc = subprocess.Popen(args + list(extra), stdout=subprocess.PIPE, text=True)
        self.pty = self.proc.stdout.readline().strip()
        self.ser = serial.Serial(self.pty, 115200, timeout=0.2)
        self.ctl = open(os.open(self.fifo, os.O_WRONLY), "w")
        # The boot line may come before the port is opened (pyserial flushes input on open): sync with a ping.
        for _ in range(20):
            self.ser.write(b"ping\n")
            if self.ser.read_until(b"pong\n").endswith(b"pong\n"):
                break
        self.ser.timeout = 5  # generous: a busy machine can starve the simulator
        # A ping answered after its 0.2 s leaves a pong behind that the next command would read as its answer: an
        # unknown command's "err" comes after every one of them.
        self.ser.write(b"sync\n")
        assert self.ser.read_until(b"err\n").endswith(b"err\n"), "no answer to the sync"

    def line(self):
        return self.ser.readline().decode().strip()

    def cmd(self, text):
        self.ser.write((text + "\n").encode())
        return self.line()

    def control(self, text):
        self.ctl.write(text + "\n")
        self.ctl.flush()

    def wait_idle(self, timeout=5.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if self.cmd("q") == "left 0":
                return
            time.sleep(0.02)
        raise AssertionError("test ELF still stepping")

    def quit(self):
        self.control("quit")
        assert self.proc.wait(timeout=5) == 0
        return json.loads(self.json.read_text())


@pytest.fixture
def sim(tmp_path):
    s = Sim(tmp_path)
    yield s
    if s.proc.poll() is None:
        s.proc.kill()
        s.proc.wait()


def test_pty_path_first_and_echo(sim):
    assert sim.pty.startswith("/dev/pts/")
    assert sim.cmd("ping") == "pong"
    assert sim.cmd("bogus") == "err"
    sim.control(f"stats {sim.json.with_name('window.json')}")  # a new window: the next exchanges only
    time.sleep(0.05)
    for _ in range(3):
        assert sim.cmd("ping") == "pong"
    uart = sim.quit()["uart"]
    assert uart["exchanges"] == 3
    # "ping\n" in, "pong\n" out: 5 bytes received, then 4 more byte times until the 5th UDR0 write, at 10 bits
    # (8N1) per byte: 1360 cycles at UBRR0 = 16 with U2X0. 11-bit bytes (simavr's own timing) would exceed it.
    assert 9 * 1360 <= uart["mean_exchange_cycles"] <= 9 * 1360 + 1200, uart


def test_step_counts_with_direction_and_isr(sim):
    # J1 and J5 backwards (DIR low), J3 forwards: 300 pulses each, then 120 more forwards on J1.
    assert sim.cmd("step 0x15 300 0x04") == "ok"
    sim.wait_idle()
    assert sim.cmd("step 0x01 120 0x01") == "ok"
    sim.wait_idle()
    out = sim.quit()
    assert out["steps"] == [-300 + 120, 0, 300, 0, -300, 0]
    assert out["pulses"] == [420, 0, 300, 0, 300, 0]
    isr = out["isr"]
    assert isr["vector"] == STEP_VECTOR
    assert isr["step_calls"] == 420          # one call per pulse batch
    assert isr["pulses"] == 1020
    assert 0 < isr["mean_cycles"] <= isr["max_cycles"] < CYCLES_PER_TICK
    assert isr["step_mean_cycles"] > isr["mean_cycles"]  # stepping calls do more than idle ones
    assert isr["count"] >= isr["step_calls"]
    assert out["estop_latency_cycles"] is None
    assert out["cycles"] > 420 * CYCLES_PER_TICK


def test_inputs_follow_control(sim):
    assert sim.cmd("in") == "in 0"
    sim.control("limit 2 1")
    sim.control("limit 6 1")
    time.sleep(0.05)
    assert sim.cmd("in") == f"in {2 | 32}"
    sim.control("limit 2 0")
    sim.control("estop 1")
    time.sleep(0.05)
    assert sim.cmd("in") == f"in {32 | 64}"


@pytest.mark.parametrize("lag", [0, 25])
def test_estop_latency(sim, lag):
    assert sim.cmd(f"lag {lag}") == "ok"
    assert sim.cmd("step 0x3f 20000 0x3f") == "ok"
    time.sleep(0.1)
    sim.control("estop 1")
    sim.wait_idle()
    out = sim.quit()
    assert out["estop_events"] == 1
    left = out["pulses"][0]
    assert 0 < left < 20000 and out["pulses"] == [left] * 6
    latency = out["estop_latency_cycles"]
    assert 0 < out["estop_isr_reaction_cycles"] <= CYCLES_PER_TICK  # the ISR's next tick sees the input
    # The edge lands anywhere in a tick, possibly inside an ISR already past its e-stop test (one more pulse).
    isr_max = out["isr"]["max_cycles"]
    if lag == 0:
        assert latency <= isr_max
    else:
        # lag more pulses, one per tick, after the edge
        assert (lag - 1) * CYCLES_PER_TICK < latency <= lag * CYCLES_PER_TICK + isr_max


def test_eeprom_survives_reset_and_restart(tmp_path):
    ee = tmp_path / "ee.bin"
    s = Sim(tmp_path, eeprom=ee)
    try:
        assert s.cmd("er") == "ee 255"  # erased
        assert s.cmd("ew 77") == "ok"
        s.control("reset")
        assert s.line() == "boot 0"
        assert s.cmd("er") == "ee 77"
        s.quit()
        assert ee.read_bytes()[0] == 77
        s2 = Sim(tmp_path, eeprom=ee)
        assert s2.cmd("er") == "ee 77"
        s2.proc.send_signal(signal.SIGTERM)
        assert s2.proc.wait(timeout=5) == 0
        assert json.loads(s2.json.read_text())["steps"] == [0] * 6
    finally:
        for p in (s, locals().get("s2")):
            if p and p.proc.poll() is None:
                p.proc.kill()


def test_interrupt_priority_loses_nothing(sim):
    # Two pending vectors, the lower-priority one older: both run, every time.
    assert sim.cmd("prio") == "prio 1 1"
    assert sim.cmd("prio") == "prio 2 2"
    out = sim.quit()
    assert out["vectors"]["1"]["count"] == 2 and out["vectors"]["8"]["count"] == 2


def test_watchdog_reset_reboots(sim):
    sim.ser.write(b"hang\n")
    assert sim.line() == "boot 1"   # WDRF set: the watchdog, not a crash, restarted it
    assert sim.cmd("ping") == "pong"


def cpu_seconds(pid):
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


def test_paced_to_real_time(sim):
    t = time.monotonic()
    time.sleep(1.0)
    out = sim.quit()
    wall = time.monotonic() - t
    seconds = out["cycles"] / 16e6
    # Never ahead of the wall clock; behind only when the machine starves it of CPU (then by a bounded debt).
    assert seconds <= wall + 0.3
    assert seconds > 0.3


def test_fast_runs_ahead_of_real_time(tmp_path):
    s = Sim(tmp_path, "--fast")
    try:
        time.sleep(0.5)
        cpu = cpu_seconds(s.proc.pid)
        out = s.quit()
        # Unpaced, each CPU second simulates well over a second (about 3-4 s on this machine's cores).
        assert out["cycles"] / 16e6 > 1.5 * cpu > 0
    finally:
        if s.proc.poll() is None:
            s.proc.kill()


def test_missing_elf_is_an_error(tmp_path):
    r = subprocess.run([AVRSIM, "--elf", str(tmp_path / "none.elf")], capture_output=True, text=True, timeout=10)
    assert r.returncode == 2
    assert "none.elf" in r.stderr
    assert r.stdout == ""
