"""cli.py - `tools/rbx1-harness`: runs the conformance suite against --port (a real board or a simulator's pty)
or against a simulator it starts itself (--sim), and prints PASS/FAIL/SKIP per check and 'N passed, N failed'."""
import argparse

from rbx1proto.link import LinkError

from . import checks_link, checks_motion, checks_safety, checks_config  # noqa: F401  (register the checks)
from .board import Board
from .runner import CHECKS, run
from .sim import Simulator


def main(argv=None):
    ap = argparse.ArgumentParser(prog="rbx1-harness", description=__doc__)
    where = ap.add_mutually_exclusive_group()
    where.add_argument("--port", help="serial port or pty of the device under test")
    where.add_argument("--sim", help="start this simulator (build/bin/rbx1-simfw or rbx1-avrsim) and test it")
    ap.add_argument("--control", help="the simulator's control FIFO (e-stop, limits, reset checks need it)")
    ap.add_argument("--baud", type=int, default=115200)
    ap.add_argument("--timeout", type=float, default=0.3, help="seconds before a retransmission (default 0.3)")
    ap.add_argument("--retries", type=int, default=10, help="retransmissions before the link is declared down")
    ap.add_argument("--boot-wait", type=float, default=0.0,
                    help="seconds of silence after opening the port before the first HELLO: opening an Arduino's "
                         "port resets it, and the Mega's bootloader keeps any byte of its first 0.83 s (2 is safe)")
    ap.add_argument("--sim-arg", action="append", default=[], help="extra argument for --sim (repeatable)")
    ap.add_argument("--clock-slack", type=float, default=0.0,
                    help="seconds the device's clock may run behind the wall clock and catch up (a simulator paced "
                         "to real time that fell behind: rbx1-avrsim); 0 for a real board and rbx1-simfw")
    ap.add_argument("--clock-file", help="the simulator's clock (its --clock-file: rbx1-avrsim, rbx1-avrboard): "
                                         "timeouts, silences and durations count on it, not on the wall clock")
    ap.add_argument("--sim-clock", action="store_true",
                    help="with --sim: give the simulator a private --clock-file and count on it (rbx1-avrsim)")
    ap.add_argument("-k", action="append", dest="select", help="run only checks whose name contains this")
    ap.add_argument("--list", action="store_true", help="list the checks and exit")
    args = ap.parse_args(argv)

    if args.list:
        for name, _, control in CHECKS:
            print(name + ("  (needs --control)" if control else ""))
        return 0
    if not args.port and not args.sim:
        ap.error("one of --port or --sim is required")
    sim = None
    try:
        if args.sim:
            sim = Simulator(args.sim, args.sim_arg, clock=args.sim_clock)
            args.port, args.control = sim.port, sim.control
            args.clock_file = sim.clock_file or args.clock_file
            print(f"# {' '.join(sim.args)} -> {sim.port}")
        try:
            board = Board(args.port, args.baud, args.control, args.timeout, args.retries, args.boot_wait,
                          args.clock_file)
            board.clock_slack = args.clock_slack
        except (LinkError, OSError, AssertionError) as e:
            print(f"FAIL  connect: {args.port}: {e}")
            print("0 passed, 1 failed")
            return 1
        try:
            passed, failed, skipped = run(board, args.select)
        finally:
            board.close()
        if sim:
            code = sim.stop()
            sim = None
            if code != 0:
                print(f"FAIL  simulator_exit: exit code {code} after quit")
                failed += 1
            else:
                print("PASS  simulator_exit")
                passed += 1
        print(f"{passed} passed, {failed} failed" + (f", {skipped} skipped" if skipped else ""))
        return 1 if failed else 0
    finally:
        if sim:
            sim.stop()
