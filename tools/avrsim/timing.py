#!/usr/bin/python3
"""timing.py - step timing of the real firmware ELF, from rbx1-avrsim's pin-level trace (--trace): runs a move set
(one joint and six joints at the 20 kHz cap, an odd-ratio move, one of two segments, a slow one with chunked
waits, STATUS polled throughout, e-stops at random phases), then analyses the trace: exact counts, shortest step interval against the commanded one, STEP pulse
width, step-ISR cycles per step, the step interrupt's wait from compare match to entry, every interrupts-off window
(from the SREG I bit), OCR1A writes against the running count, and the e-stop input edge to the last STEP edge.
Used by tools/avrsim/test/test_timing.py (thresholds) and tools/bench/firmware (figures).
Usage: timing.py [--trials N] [--json OUT] [--keep-trace FILE]"""
import argparse
import json
import os
import random
import subprocess
import sys
import tempfile
import time

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "protocol", "python"))
sys.path.insert(0, os.path.join(ROOT, "tools", "harness"))
from rbx1proto.link import Link  # noqa: E402
from rbx1proto.messages import JOINTS, PROTO_VERSION, Key, MsgType, State, Status  # noqa: E402
from rbx1_harness.sim_clock import HZ, SimClock  # noqa: E402

AVRSIM = os.environ.get("AVRSIM", os.path.join(ROOT, "build", "bin", "rbx1-avrsim"))
ELF = os.environ.get("RBX1_FIRMWARE_ELF", os.path.join(ROOT, "build", "firmware", "rbx1.elf"))
STEP_VECTOR = 17          # TIMER1_COMPA on the ATmega2560
CAP = 20000               # steps/s: MAX_SPEED's configurable maximum
CAP_INTERVAL = HZ / CAP   # 800 cycles


def analyse(path, phases=(), step_vector=STEP_VECTOR):
    """Figures from a trace file (format: tools/avrsim/trace.hpp). phases: (label, first cycle, last cycle) windows
    (one move each) for which the step ISR's cycles per step are given: all its cycles in the window / pulses."""
    per_phase = [[label, a, b, 0, 0, 0, 0] for label, a, b in phases]  # + calls, cycles, max cycles, pulses
    level = [0] * JOINTS
    dirs = [0] * JOINTS
    net = [0] * JOINTS
    pulses = [0] * JOINTS
    last_rise = [None] * JOINTS
    min_interval = [None] * JOINTS
    min_width = None
    stack = []                 # running vectors: [vector, entry cycle, pulses raised]
    pending_at = None          # step vector raised (compare match) and not yet entered
    wait_max = 0
    step_calls = {}            # pulses raised in the call -> [calls, total cycles, max cycles]
    off_at = None              # cycle the I bit went to 0
    off_ctx = None
    windows = {}               # context -> max interrupts-off window
    worst_window = (0, None, None, None)
    step_isr_off_max = 0
    ocr_writes = 0
    ocr_min_margin = None
    ocr_late = 0               # writes at or below the running count (a missed match on silicon)
    estop_edges = []           # [edge cycle, last rise after it or None]
    short_windows = short_max = 0
    with open(path) as f:
        for line in f:
            if line[0] == "#":
                continue
            p = line.split()
            k, c = p[0], int(p[1])
            if k == "S":
                j, v = int(p[2]), int(p[3])
                if v == level[j]:
                    continue
                level[j] = v
                if v:
                    pulses[j] += 1
                    net[j] += 1 if dirs[j] else -1
                    if last_rise[j] is not None:
                        d = c - last_rise[j]
                        if min_interval[j] is None or d < min_interval[j]:
                            min_interval[j] = d
                    last_rise[j] = c
                    if stack:
                        stack[-1][2] += 1
                    if estop_edges and estop_edges[-1][2]:
                        estop_edges[-1][1] = c
                elif last_rise[j] is not None:
                    w = c - last_rise[j]
                    if min_width is None or w < min_width:
                        min_width = w
            elif k == "D":
                dirs[int(p[2])] = int(p[3])
            elif k == "P":
                if int(p[2]) == step_vector:
                    pending_at = c
            elif k == "E":
                v = int(p[2])
                if v == step_vector and pending_at is not None:
                    wait_max = max(wait_max, c - pending_at)
                    pending_at = None
                stack.append([v, c, 0])
            elif k == "X":
                if stack and stack[-1][0] == int(p[2]):
                    v, c0, n = stack.pop()
                    if v == step_vector:
                        for ph in per_phase:
                            if ph[1] <= c0 <= ph[2]:
                                ph[3] += 1
                                ph[4] += c - c0
                                ph[5] = max(ph[5], c - c0)
                                ph[6] += n
                    if v == step_vector and n:
                        s = step_calls.setdefault(n, [0, 0, 0])
                        s[0] += 1
                        s[1] += c - c0
                        s[2] = max(s[2], c - c0)
            elif k == "W":
                w, where = int(p[2]), p[3]
                if c == 0:
                    continue  # power-up: interrupts stay off until the Arduino core's init() enables them
                if where in (f"e{step_vector}", f"c{step_vector}"):
                    step_isr_off_max = max(step_isr_off_max, w)
                else:
                    name = {"m": "main loop"}.get(where, f"{'entry of' if where[0] == 'e' else 'cli in'} vector {where[1:]}")
                    windows[name] = max(windows.get(name, 0), w)
                    if w > worst_window[0]:
                        worst_window = (w, name, c, p[4])
            elif k == "w":
                short_windows, short_max = int(p[1]), int(p[2])
            elif k == "O":
                ocr, tcnt = int(p[2]), int(p[3])
                ocr_writes += 1
                m = ocr - tcnt
                if ocr_min_margin is None or m < ocr_min_margin:
                    ocr_min_margin = m
                if m <= 0:
                    ocr_late += 1
            elif k == "K":
                if p[2] == "1":
                    estop_edges.append([c, None, True])
                elif estop_edges:
                    estop_edges[-1][2] = False
    moves = {ph[0]: {"isr_calls": ph[3], "isr_cycles": ph[4], "isr_max_cycles": ph[5], "pulses": ph[6],
                     "cycles_per_step": ph[4] / ph[6] if ph[6] else None,
                     "cycles_per_call": ph[4] / ph[3] if ph[3] else None} for ph in per_phase}
    latencies = [(e[1] - e[0]) if e[1] is not None else 0 for e in estop_edges]
    return {
        "net_steps": net, "pulses": pulses, "min_interval_cycles": min_interval,
        "min_pulse_width_cycles": min_width,
        "step_isr_by_pulses_per_call": {str(n): {"calls": s[0], "mean_cycles": s[1] / s[0], "max_cycles": s[2]}
                                        for n, s in sorted(step_calls.items())},
        "step_isr_by_move": moves,
        "step_isr_wait_max_cycles": wait_max,
        "irq_off_windows_max_cycles": windows,
        "irq_off_short_windows": short_windows, "irq_off_short_max_cycles": short_max,
        "irq_off_window_max_cycles": worst_window[0],
        "irq_off_window_worst_where": worst_window[1], "irq_off_window_worst_cycle": worst_window[2],
        "irq_off_window_worst_pc": worst_window[3],
        "step_isr_irq_off_max_cycles": step_isr_off_max,
        "ocr1a_writes": ocr_writes, "ocr1a_min_margin_ticks": ocr_min_margin, "ocr1a_late_writes": ocr_late,
        "estop_trials": len(estop_edges), "estop_latency_cycles": latencies,
        "estop_latency_max_cycles": max(latencies) if latencies else None,
        "estop_trials_with_late_pulse": sum(1 for e in estop_edges if e[1] is not None),
    }


def function_address(elf, name):
    """The flash byte address of the function `name` (unmangled, as `avr-nm -C` prints it: LTO may add a clone
    suffix) in elf; the function must be out of line."""
    out = subprocess.run(["avr-nm", "-C", elf], capture_output=True, text=True, check=True).stdout
    for line in out.splitlines():
        p = line.split(None, 2)
        if len(p) == 3 and p[1] in "Tt" and p[2].startswith(name + "("):
            return int(p[0], 16)
    raise RuntimeError(f"{elf}: no function {name} (inlined?)")


class HostTurn:
    """A pyserial port telling rbx1-avrsim (--hold-for-host) when the host is busy: from the moment a read returns
    until the next read begins (deciding, writing), the board's time stands still, so a host descheduled in its turn
    costs no simulated time: a loaded machine slows the run down but does not change what the firmware sees."""

    def __init__(self, ser, flag):
        self._ser, self._flag = ser, flag

    def read(self, n=1):
        self._flag[0] = 0
        try:
            return self._ser.read(n)
        finally:
            self._flag[0] = 1

    def __getattr__(self, name):
        return getattr(self._ser, name)

    def __setattr__(self, name, value):
        if name == "timeout":
            self._ser.timeout = value
        else:
            super().__setattr__(name, value)


class Board:
    """rbx1-avrsim --trace on the real ELF (--fast unless fast=False), a Link to its pty and its control FIFO. With
    hold_for_host, the simulator's time follows the host (--hold-for-host, HostTurn) and the Link times out on the
    board's clock (--clock-file): a host held up by a loaded machine is never late for the simulated arm."""

    def __init__(self, trace_path, workdir, fast=True, hold_for_host=False, elf=ELF, time_function=None):
        self.fifo = os.path.join(workdir, "control.fifo")
        self.json = os.path.join(workdir, "avrsim.json")
        clock = os.path.join(workdir, "clock")
        timed = ["--time-function", f"{function_address(elf, time_function):x}"] if time_function else []
        self.proc = subprocess.Popen([AVRSIM, "--elf", elf] + (["--fast"] if fast else []) +
                                     (["--hold-for-host", "--clock-file", clock] if hold_for_host else []) + timed +
                                     ["--trace", trace_path, "--json", self.json,
                                      "--control", self.fifo, "--max-seconds", "300"], stdout=subprocess.PIPE, text=True)
        self.link = Link(self.proc.stdout.readline().strip(), timeout=0.5, retries=10)
        self.clock = None
        if hold_for_host:  # PROTOCOL.md's 100 ms on the board's clock: a frame the bridge lost costs 2.5 moves of stream.py
            self.link.timeout = 0.1
            self.clock = SimClock(clock)  # written before the pty path
            self.link.clock = self.clock.seconds
            self.link.ser = HostTurn(self.link.ser, self.clock.busy)
        self.link.hello()
        self.ctl = os.fdopen(os.open(self.fifo, os.O_WRONLY), "w")

    def req(self, msg_type, **fields):
        r = self.link.request(msg_type, **fields)
        if r["status"] != Status.OK:
            raise RuntimeError(f"{MsgType(msg_type).name} {fields}: status {r['status']}")
        return r

    def control(self, line):
        self.ctl.write(line + "\n")
        self.ctl.flush()

    def cycle(self):
        """The simulated cycle now (from an avrsim stats snapshot)."""
        self.marks = getattr(self, "marks", 0) + 1
        path = self.json + f".{self.marks}"
        self.control(f"stats {path}")
        end = time.monotonic() + 10
        while not os.path.exists(path):
            if time.monotonic() > end:
                raise RuntimeError("rbx1-avrsim wrote no stats")
            time.sleep(0.002)
        with open(path) as f:
            return json.load(f)["cycles"]

    def wait_state(self, state, timeout=60):
        end = time.monotonic() + timeout
        while True:
            s = self.req(MsgType.STATUS)  # STATUS polled throughout: its position read runs during the moves
            if s["state"] == state and (state != State.IDLE or s["queue_free"] == self.queue):
                return s
            if time.monotonic() > end:
                raise RuntimeError(f"not in state {state}: {s}")

    def close(self):
        try:
            self.control("quit")
            self.proc.wait(timeout=20)
        except (OSError, subprocess.TimeoutExpired):
            self.proc.kill()
            self.proc.wait()
        self.link.close()
        if self.clock:
            self.clock.close()


def run(trace_path, estop_trials=20, seed=1):
    """The move set on the real ELF; returns (expected figures, avrsim JSON)."""
    rng = random.Random(seed)
    with tempfile.TemporaryDirectory(prefix="rbx1-timing-") as tmp:
        b = Board(trace_path, tmp)
        try:
            b.queue = b.req(MsgType.HELLO, proto_version=PROTO_VERSION)["queue_size"]
            b.req(MsgType.CONFIG_SET, joint=0xFF, key=Key.HEARTBEAT_MS, value=60000)  # --fast: sim time races
            for j in range(JOINTS):
                b.req(MsgType.CONFIG_SET, joint=j, key=Key.MAX_SPEED, value=CAP)
                b.req(MsgType.CONFIG_SET, joint=j, key=Key.ACCEL, value=200000)
            b.req(MsgType.ENABLE, enable=1)
            b.req(MsgType.SET_POSITION, position=[0] * JOINTS)
            moves = [("1 joint", [4000, 0, 0, 0, 0, 0]),           # one joint cruising at the cap
                     ("1 joint back", [0, 0, 0, 0, 0, 0]),
                     ("6 joints", [4000, -4000, 4000, -4000, 4000, -4000]),  # six together at the cap
                     ("odd ratios", [-1733, 4100, 977, -2500, 31, 3999]),
                     ("long", [-33000, 1, -3, 7, 0, 0]),           # over 32767 steps: two segments
                     ("slow", [-32997, 1, -3, 7, 0, 1], 600)]      # intervals over 16 bits (chunked waits)
            pos = [0] * JOINTS
            phases = []
            for label, t, *duration in moves:
                c0 = b.cycle()
                b.req(MsgType.MOVE, target=t, duration_ms=duration[0] if duration else 0)
                s = b.wait_state(State.IDLE)
                phases.append((label, c0, b.cycle()))
                if s["position"] != t:
                    raise RuntimeError(f"STATUS says {s['position']}, commanded {t}")
                pos = t
            net = list(pos)
            # E-stops at random phases: the input rises a random number of cycles after a compare match of the step
            # timer (0..2000: more than the 800-cycle interval at the cap, so every point of the interrupt is hit).
            latencies_ok = True
            for i in range(estop_trials):
                b.req(MsgType.SET_POSITION, position=[0] * JOINTS)
                sign = 1 if i % 2 == 0 else -1
                # armed before the move: on its N-th step interrupt (ramping or cruising), D cycles after the match
                b.control(f"estop 1 @{rng.randrange(0, 2000)}:{rng.randrange(1, 2500)}")
                b.cycle()  # the command has been read
                b.req(MsgType.MOVE, target=[sign * 3000] * JOINTS, duration_ms=0)
                s = b.wait_state(State.FAULT)
                b.control("estop 0")
                time.sleep(0.01)
                for _ in range(100):
                    r = b.link.request(MsgType.CLEAR_FAULT)
                    if r["status"] == Status.OK:
                        break
                    time.sleep(0.01)
                b.req(MsgType.ENABLE, enable=1)
                s = b.req(MsgType.STATUS)
                net = [n + p for n, p in zip(net, s["position"])]
                latencies_ok = latencies_ok and s["state"] == State.IDLE
        finally:
            b.close()
        with open(b.json) as f:
            sim = json.load(f)
    return {"net_steps": net, "status_ok_after_estops": latencies_ok, "phases": phases}, sim


def report(fig, json_path=None):
    """Prints a run's figures (and writes them to json_path if given, for make bench); 0, main's exit status."""
    if json_path:
        with open(json_path, "w") as f:
            json.dump(fig, f, indent=2)
    json.dump(fig, sys.stdout, indent=1)
    print()
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=20, help="e-stop trials at random phases")
    ap.add_argument("--json", help="write the figures here")
    ap.add_argument("--keep-trace", help="keep the trace in this file")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="rbx1-trace-") as tmp:
        trace = args.keep_trace or os.path.join(tmp, "trace.txt")
        expected, sim = run(trace, args.trials)
        fig = analyse(trace, expected["phases"])
    fig["expected_net_steps"] = expected["net_steps"]
    fig["exact"] = fig["net_steps"] == expected["net_steps"] == sim["steps"]
    fig["min_interval_ratio_at_cap"] = min(i for i in fig["min_interval_cycles"] if i) / CAP_INTERVAL
    return report(fig, args.json)


if __name__ == "__main__":
    sys.exit(main())
