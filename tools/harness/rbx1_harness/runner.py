"""runner.py - registers checks, runs them in order with a fresh board state each, and prints the summary line."""
import time
import traceback

CHECKS = []  # (name, function, needs_control)


class Skip(Exception):
    """Raised by a check that cannot run here (e.g. no control FIFO on a real board)."""


class CheckFailed(AssertionError):
    pass


def check(name, control=False):
    """Decorator: registers fn(board) as a conformance check. control=True: needs the simulator's control FIFO."""
    def wrap(fn):
        CHECKS.append((name, fn, control))
        return fn
    return wrap


def expect(cond, message):
    if not cond:
        raise CheckFailed(message)


def run(board, select=None, out=print):
    """Runs the selected checks; returns (passed, failed, skipped)."""
    passed = failed = skipped = 0
    for name, fn, needs_control in CHECKS:
        if select and not any(s in name for s in select):
            continue
        t0 = time.monotonic()
        try:
            if needs_control and not board.control:
                raise Skip("needs the simulator's control FIFO (--control); not available on a real board")
            board.prepare()
            fn(board)
            passed += 1
            out(f"PASS  {name}  ({time.monotonic() - t0:.2f} s)")
        except Skip as e:
            skipped += 1
            out(f"SKIP  {name}: {e}")
        except AssertionError as e:
            failed += 1
            out(f"FAIL  {name}: {e}")
        except Exception as e:  # a link error or a bug: report it as a failure with its place
            failed += 1
            where = traceback.extract_tb(e.__traceback__)[-1]
            out(f"FAIL  {name}: {type(e).__name__}: {e} ({where.filename.split('/')[-1]}:{where.lineno})")
    return passed, failed, skipped
