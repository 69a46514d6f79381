"""test_cli_progress.py - `rbx1 pick` on a terminal (a pseudo-terminal) keeps one progress line updated in place with
\\r (phase, steps done of the plan's total, elapsed), erased before each permanent line; piped, the output has no \\r
and no escape, and its lines are the terminal's permanent ones."""
import fcntl
import os
import pty
import re
import struct
import subprocess
import termios
import tty

import rbx1e2e as e2e

# One update: "\r" + "pick: approach, 12 of 69 steps, 1.2 s" + ESC[K (the rest of a longer line before it); an erase
# is the same with nothing between.
UPDATE = re.compile(r"\r([^\r\n\x1b]*)\x1b\[K")
PROGRESS = re.compile(r"pick: ([a-z_]+)(?:, (\d+) of (\d+) steps)?, (\d+\.\d) s$")
COLUMNS = 100


def run_on_pty(args):
    """The command's stdout through a pty (raw: no \\n -> \\r\\n, so every \\r is the program's), stderr piped."""
    master, slave = pty.openpty()
    tty.setraw(slave)
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, COLUMNS, 0, 0))
    proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=slave, stderr=subprocess.PIPE)
    os.close(slave)
    out = b""
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:  # EIO: the last writer closed the slave
            break
        if not chunk:
            break
        out += chunk
    os.close(master)
    proc.wait(timeout=60)
    return proc.returncode, out.decode(), proc.stderr.read().decode()


def masked(text):
    """A line with its numbers masked: two runs of the same pick differ only in times and measured values."""
    return [re.sub(r"-?\d+(\.\d+)?(e-?\d+)?", "N", l) for l in text.splitlines()]


def test_pick_shows_one_progress_line_on_a_terminal(sim, daemon_factory):
    d = daemon_factory(sim.port)
    label = e2e.scene_labels()[0]
    cmd = [e2e.need(e2e.BIN / "rbx1"), "pick", label, "--place", "tray", "--socket", d.socket]
    rc, out, err = run_on_pty(cmd)
    assert rc == 0, (out, err)

    updates = [u for u in UPDATE.findall(out) if u]
    assert len(updates) >= 10, out
    parsed = [PROGRESS.match(u) for u in updates]
    assert all(parsed), [u for u, p in zip(updates, parsed) if not p]
    assert all(len(u) < COLUMNS for u in updates)
    # Elapsed never goes back; the plan's steps rise one by one (a step_done each) to its total, which is the
    # result's step count, and the phases are the plan's.
    elapsed = [float(p[4]) for p in parsed]
    assert elapsed == sorted(elapsed), elapsed
    counted = [(int(p[2]), int(p[3])) for p in parsed if p[2]]
    total = int(re.search(r"^steps: (\d+)$", out, re.M)[1])
    assert {t for _, t in counted} == {total}, counted
    done = [n for n, _ in counted]
    assert done == sorted(done) and done[-1] == total, done
    assert set(range(1, total + 1)) <= set(done), "a step_done without its update"
    phases = {p[1] for p in parsed if p[2]}
    assert {"approach", "descend", "lift", "carry", "home"} <= phases, phases

    # Every update is erased before a permanent line: what is left has no \r or escape, and the final lines are
    # intact at the end.
    permanent = UPDATE.sub("", out)
    assert "\r" not in permanent and "\x1b" not in permanent, repr(permanent[-400:])
    assert out.endswith(permanent[permanent.rindex("\npicked: ") + 1:]), repr(out[-400:])
    assert re.search(rf"^picked: {label}$", permanent, re.M), permanent

    # Piped (not a terminal): no progress line, and the same permanent lines.
    piped = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert piped.returncode == 0, piped.stderr
    assert "\r" not in piped.stdout and "\x1b" not in piped.stdout
    assert masked(piped.stdout) == masked(permanent), (piped.stdout, permanent)
    assert any(re.match(r" *\d+\.\d{3} s  moved +approach +\d+ segments", l) for l in piped.stdout.splitlines())

    # --verbose and --json keep their lines as they were: no progress on the terminal either.
    for flag in ("--verbose", "--json"):
        rc, out, err = run_on_pty(cmd + [flag])
        assert rc == 0 and "\r" not in out and "\x1b" not in out, (flag, out[-400:], err)
