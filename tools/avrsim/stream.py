#!/usr/bin/python3
"""stream.py - the look-ahead on the real firmware ELF: streams a list of MOVE targets (a circle of 500 short moves by
default) to rbx1-avrsim --trace (real time) as fast as the queue takes them, then measures from the pin-level trace: exact counts,
the longest gap between STEP pulses mid-stream against the slowest junction speed of the rule (firmware/README.md,
Look-ahead), every joint's speed and acceleration from the step timestamps, STEP pulse width and DIR setup time,
the profile tick's cycles, each answer's latency (last request byte in to first answer byte out), the look-ahead's
passes (planner_recalculate's cycles, from the trace's timed function), and the interrupts-off windows and compare writes (tools/avrsim/timing.py's analysis).
Used by tools/avrsim/test/test_lookahead.py (thresholds) and tools/bench/motion (figures).
Usage: stream.py [--moves N] [--json OUT]"""
import argparse
import json
import math
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.realpath(__file__)))
import timing  # noqa: E402
from timing import HZ, JOINTS, Board, MsgType, State, Status  # noqa: E402

SPEED_W = 0.02   # s: speed over windows of this length (tolerance: one step per window)
ACCEL_W = 0.1    # s: acceleration as the second difference of positions over windows of this length (4 steps / W^2)
VMAX = [2000, 2000, 4000, 4000, 4000, 4000]    # MAX_SPEED per joint, steps/s
ACCEL = [20000, 20000, 8000, 8000, 8000, 8000]  # ACCEL per joint, steps/s^2


def _config(name):
    """A #define of firmware/rbx1/src/config.h (the single source)."""
    path = os.path.join(os.path.dirname(os.path.realpath(__file__)), "..", "..", "firmware", "rbx1", "src", "config.h")
    with open(path) as f:
        for line in f:
            p = line.split()
            if len(p) >= 3 and p[0] == "#define" and p[1] == name:
                return int(p[2].rstrip("UL"))
    raise KeyError(f"{name} not in {path}")


JUNCTION_LAG_STEPS = _config("JUNCTION_LAG_STEPS")  # the junction rule's jump: sqrt(2 ACCEL lag)


def circle(n=500, r=5787.0, turns=1.1):
    """n moves along `turns` of a circle of radius r steps in J1/J2 from 0 (the default: 57..80 dominant steps each,
    40 ms at 2000 steps/s, so that sixteen queued moves keep 0.6 s of motion ahead of a host slowed by the load)."""
    a = [2 * math.pi * turns * k / n for k in range(1, n + 1)]
    return [[round(r * math.cos(x) - r), round(r * math.sin(x)), 0, 0, 0, 0] for x in a]


def junction_speed(a, b, c, vmax=VMAX, acc=ACCEL):
    """The rule, independently of planner.cpp: the largest dominant rate at the junction of moves a -> b -> c."""
    da = [y - x for x, y in zip(a, b)]
    db = [y - x for x, y in zip(b, c)]
    na, nb = max(map(abs, da)), max(map(abs, db))
    v = min([vmax[i] * na / abs(da[i]) for i in range(JOINTS) if da[i]] +
            [vmax[i] * nb / abs(db[i]) for i in range(JOINTS) if db[i]])
    for i in range(JOINTS):
        d = abs(da[i] / na - db[i] / nb)
        if d > 0:
            v = min(v, math.sqrt(2 * acc[i] * JUNCTION_LAG_STEPS) / d, math.sqrt(acc[i] * min(na, nb) / d))
    return v


def run(trace_path, targets, duration_ms=0, vmax=VMAX, acc=ACCEL, elf=timing.ELF):
    """Streams targets (from position 0) to the real ELF in real time (under --fast the simulation outruns a host
    that the machine's load holds up, and the queue runs empty); returns (STATUS after, avrsim JSON, MOVEs refused
    as QUEUE_FULL, the moves (counted from 1) after the third accepted with at most three in the queue: the host
    fell behind)."""
    try:  # the host must keep ahead of the simulated arm: ask for the share rbx1-avrsim asks for (root only)
        os.setpriority(os.PRIO_PROCESS, 0, -10)
    except OSError:
        pass
    with tempfile.TemporaryDirectory(prefix="rbx1-stream-") as tmp:
        b = Board(trace_path, tmp, fast=False, hold_for_host=True, elf=elf, time_function=TIMED)
        full, starved = 0, []
        try:
            b.queue = b.req(MsgType.HELLO, proto_version=timing.PROTO_VERSION)["queue_size"]
            b.req(MsgType.CONFIG_SET, joint=0xFF, key=timing.Key.HEARTBEAT_MS, value=60000)
            for j in range(JOINTS):
                b.req(MsgType.CONFIG_SET, joint=j, key=timing.Key.MAX_SPEED, value=vmax[j])
                b.req(MsgType.CONFIG_SET, joint=j, key=timing.Key.ACCEL, value=acc[j])
            b.req(MsgType.ENABLE, enable=1)
            b.req(MsgType.SET_POSITION, position=[0] * JOINTS)
            before = b.req(MsgType.STATUS)
            k = 0
            while k < len(targets):
                r = b.link.request(MsgType.MOVE, target=targets[k], duration_ms=duration_ms)
                if r["status"] == Status.OK:
                    k += 1
                    # Three moves or fewer queued with it: less than the look-ahead needs to keep the speed (a
                    # ramp to rest spans two moves of the default circle), so the arm slowed or stopped, as it must.
                    if k > 3 and r["queue_free"] >= b.queue - 3:
                        starved.append(k)
                elif r["status"] == Status.QUEUE_FULL:
                    full += 1
                else:
                    raise RuntimeError(f"MOVE {k}: status {r['status']}")
            s = b.wait_state(State.IDLE)
            s["moves"] = (s["moves_done"] - before["moves_done"]) % 65536
        finally:
            b.close()
        with open(b.json) as f:
            sim = json.load(f)
    return s, sim, full, starved


PROFILE_VECTOR = 32  # TIMER3_COMPA: the 1 kHz profile tick
TIMED = "planner_recalculate"  # the look-ahead's passes (out of line so that the trace can time them)


def passes(trace_path):
    """The look-ahead's passes (planner_recalculate's calls, the trace's "F" lines): (count, median own cycles, largest
    own cycles, largest with the interrupts inside it)."""
    own, wall = [], []
    with open(trace_path) as f:
        for line in f:
            if line[0] == "F":
                _, _, w, o = line.split()
                wall.append(int(w))
                own.append(int(o))
    own.sort()
    if not own:
        return 0, None, None, None
    return len(own), own[len(own) // 2], own[-1], max(wall)
RX_VECTOR, UDRE_VECTOR = 25, 26  # USART0_RX and USART0_UDRE


def answer_latency(trace_path):
    """Cycles from each request's last byte in (its last RX interrupt before an answer) to the answer's first byte
    out (the next UDRE interrupt): the host streams one request at a time, so each RX burst is one request. All
    answers count, QUEUE_FULL refusals included. Returns (median, 90th percentile, maximum, count)."""
    lat, last_rx = [], None
    with open(trace_path) as f:
        for line in f:
            if line[0] != "E":
                continue
            c, v = map(int, line.split()[1:3])
            if v == RX_VECTOR:
                last_rx = c
            elif v == UDRE_VECTOR and last_rx is not None:
                lat.append(c - last_rx)
                last_rx = None
    lat.sort()
    if not lat:
        return None, None, None, 0
    return lat[len(lat) // 2], lat[min(len(lat) - 1, len(lat) * 9 // 10)], lat[-1], len(lat)


def analyse(trace_path, ticks=None):
    """Per joint: STEP rise cycles with the direction (+1/-1), the shortest pulse, the shortest DIR-to-STEP setup.
    ticks (a list) gets the cycles of every profile tick (entry to exit, the step interrupts it let in included)."""
    steps = [[] for _ in range(JOINTS)]
    level, dirs, rise = [0] * JOINTS, [0] * JOINTS, [None] * JOINTS
    dir_at = [None] * JOINTS
    width = setup = None
    stack = []
    with open(trace_path) as f:
        for line in f:
            if line[0] == "E":
                stack.append((int(line.split()[2]), int(line.split()[1])))
                continue
            if line[0] == "X":
                p = line.split()
                if stack and stack[-1][0] == int(p[2]):
                    v, c0 = stack.pop()
                    if v == PROFILE_VECTOR and ticks is not None:
                        ticks.append(int(p[1]) - c0)
                continue
            if line[0] not in "SD":
                continue
            k, c, j, v = line.split()[:4]
            c, j, v = int(c), int(j), int(v)
            if k == "D":
                if v != dirs[j]:
                    dir_at[j] = c
                dirs[j] = v
            elif v != level[j]:
                level[j] = v
                if v:
                    steps[j].append((c, 1 if dirs[j] else -1))
                    rise[j] = c
                    if dir_at[j] is not None:
                        setup = c - dir_at[j] if setup is None else min(setup, c - dir_at[j])
                        dir_at[j] = None
                elif rise[j] is not None:
                    width = c - rise[j] if width is None else min(width, c - rise[j])
    return steps, width, setup


def limits(steps, t0, t1):
    """Largest speed and acceleration per joint (steps/s, steps/s^2) from the positions at 1 ms steps."""
    ms = HZ // 1000
    speed, accel = [0.0] * JOINTS, [0.0] * JOINTS
    ks, ka = round(SPEED_W * 1000), round(ACCEL_W * 1000)
    for j in range(JOINTS):
        if not steps[j]:
            continue
        p, pos, i = [], 0, 0
        for t in range(t0, t1 + 1, ms):
            while i < len(steps[j]) and steps[j][i][0] <= t:
                pos += steps[j][i][1]
                i += 1
            p.append(pos)
        speed[j] = max((abs(p[k + ks] - p[k]) / SPEED_W for k in range(len(p) - ks)), default=0.0)
        accel[j] = max((abs(p[k + 2 * ka] - 2 * p[k + ka] + p[k]) / ACCEL_W ** 2 for k in range(len(p) - 2 * ka)),
                       default=0.0)
    return speed, accel


def arrivals(steps, targets):
    """The cycle at which the joints reached each target in turn (moves end exactly at their targets)."""
    events = sorted((c, j, d) for j in range(JOINTS) for c, d in steps[j])
    pos, out = [0] * JOINTS, []
    for c, j, d in events:
        pos[j] += d
        while len(out) < len(targets) and pos == targets[len(out)]:
            out.append(c)
    return out


def figures(trace_path, targets, starved=(), vmax=VMAX, acc=ACCEL):
    """Everything the test checks, from the trace. starved: moves (counted from 1) accepted with at most three in the
    queue (the host fell behind): the arm had to slow down or stop around them, so the gaps from three moves before
    to two after are left out of the mid-stream figure (a ramp to rest and back spans two moves of the default
    circle) and counted apart."""
    ticks = []
    steps, width, setup = analyse(trace_path, ticks)
    all_t = sorted(c for s in steps for c, _ in s)
    ramp = max(v / a for v, a in zip(vmax, acc)) + 0.05  # s of the ramps at both ends, and a margin
    mid0, mid1 = all_t[0] + ramp * HZ, all_t[-1] - ramp * HZ
    arr = arrivals(steps, targets)
    skip = [(arr[max(k - 4, 0)], arr[min(k + 2, len(arr) - 1)]) for k in starved if k - 4 >= 0 and k < len(arr)]
    gaps = [(b - a) for a, b in zip(all_t, all_t[1:])]
    mid = [(b - a, a) for a, b in zip(all_t, all_t[1:])
           if a >= mid0 and b <= mid1 and not any(s0 <= a and b <= s1 for s0, s1 in skip)]
    worst = max(mid)
    worst_at = sum(1 for c in arr if c <= worst[1])  # moves completed when the longest mid-stream gap began
    prev = [0] * JOINTS
    vj = math.inf
    for k in range(len(targets) - 1):
        vj = min(vj, junction_speed(prev, targets[k], targets[k + 1], vmax, acc))
        prev = targets[k]
    speed, accel = limits(steps, all_t[0], all_t[-1])
    v0 = math.sqrt(min(acc[j] for j in range(JOINTS) if steps[j]) / 2)
    t = timing.analyse(trace_path)  # interrupts-off windows and compare writes while the look-ahead works
    lat = answer_latency(trace_path)
    pa = passes(trace_path)
    return {"net_steps": [sum(d for _, d in s) for s in steps], "pulses": sum(len(s) for s in steps),
            "seconds": (all_t[-1] - all_t[0]) / HZ, "junction_speed_min": vj, "stop_rate": v0,
            "targets_reached_in_order": len(arr), "stops_left_out": len(skip),
            "max_gap_mid_s": worst[0] / HZ, "max_gap_mid_after_move": worst_at, "max_gap_s": max(gaps) / HZ,
            "max_speed": speed, "max_accel": accel, "min_pulse_width_cycles": width,
            "min_dir_setup_cycles": setup, "profile_tick_max_cycles": max(ticks, default=None),
            "profile_tick_mean_cycles": sum(ticks) / len(ticks) if ticks else None,
            "irq_off_window_max_cycles": t["irq_off_window_max_cycles"],
            "irq_off_windows_max_cycles": t["irq_off_windows_max_cycles"],
            "step_isr_wait_max_cycles": t["step_isr_wait_max_cycles"], "ocr1a_late_writes": t["ocr1a_late_writes"],
            "answer_latency_median_cycles": lat[0], "answer_latency_p90_cycles": lat[1],
            "answer_latency_max_cycles": lat[2], "answers_timed": lat[3],
            "passes": pa[0], "pass_median_cycles": pa[1], "pass_max_cycles": pa[2], "pass_max_with_interrupts_cycles": pa[3]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=500)
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args()
    targets = circle(args.moves)
    with tempfile.TemporaryDirectory(prefix="rbx1-trace-") as tmp:
        trace = os.path.join(tmp, "trace.txt")
        status, sim, full, starved = run(trace, targets)
        fig = figures(trace, targets, starved)
    fig.update(moves=status["moves"], position=status["position"], avrsim_steps=sim["steps"], refused_full=full,
               starved=starved)
    return timing.report(fig, args.json)


if __name__ == "__main__":
    sys.exit(main())
