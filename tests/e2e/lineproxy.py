"""lineproxy.py - a serial line between rbx1d and a simulated board, for the end-to-end tests, the benches and the
soak: a byte forwarder between the pty rbx1d opens (through a symlink) and the simulated firmware's pty (its path
or its --link symlink), timestamping each frame, with optional faults per frame and per direction.

Each whole frame crossing the line may be corrupted (one bit of one byte flipped), dropped, duplicated or delayed
(the line stalls: order is kept), each with its own probability. Bytes that are not a frame (nothing here sends
any) pass as they come. The line can be cut (an outage: every byte lost both ways), the daemon's side can vanish
and come back (a USB device unplugged and plugged in), and when the firmware side hangs up (a power-cycled
board) the proxy reopens the firmware's path as soon as it is back.
"""
import os
import random
import select
import sys
import threading
import time
import tty

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "protocol", "python"))
from rbx1proto.frame import MAX_PAYLOAD, OVERHEAD, SYNC  # noqa: E402  (the framing of the current version)


class Direction:
    """One way of the line: frame splitting, faults, and an ordered output queue with due times."""

    def __init__(self, name, rates, rng):
        self.name = name
        self.rates = rates  # dict: corrupt, drop, duplicate, delay_rate, delay_ms
        self.rng = rng
        self.buf = bytearray()
        self.buf_at = 0.0
        self.out = []  # (due, bytes), due non-decreasing
        self.counts = {"frames": 0, "corrupted": 0, "dropped": 0, "duplicated": 0, "delayed": 0}
        self.seen = []  # (monotonic ns, TYPE) of each frame as it arrived, before any fault

    def push(self, data, now):
        if not self.buf:
            self.buf_at = now
        self.buf += data
        self._split(now, flush=False)

    def _emit(self, data, now, frame):
        r = self.rates
        delay = 0.0
        if frame:
            self.counts["frames"] += 1
            self.seen.append((int(now * 1e9), data[3]))
            x = self.rng.random()
            if x < r["corrupt"]:
                data = bytearray(data)
                i = self.rng.randrange(len(data))
                data[i] ^= 1 << self.rng.randrange(8)
                data = bytes(data)
                self.counts["corrupted"] += 1
            elif x < r["corrupt"] + r["drop"]:
                self.counts["dropped"] += 1
                return
            elif x < r["corrupt"] + r["drop"] + r["duplicate"]:
                data = data + data
                self.counts["duplicated"] += 1
            if self.rng.random() < r["delay_rate"]:
                delay = r["delay_ms"] / 1000.0
                self.counts["delayed"] += 1
        due = max(now + delay, self.out[-1][0] if self.out else 0.0)
        self.out.append((due, bytes(data)))

    def _split(self, now, flush):
        b = self.buf
        while b:
            if b[0] != SYNC:
                i = b.find(SYNC)
                n = len(b) if i < 0 else i
                self._emit(bytes(b[:n]), now, False)
                del b[:n]
                continue
            if len(b) < 2:
                break
            if b[1] > MAX_PAYLOAD:
                self._emit(bytes(b[:1]), now, False)
                del b[:1]
                continue
            n = b[1] + OVERHEAD
            if len(b) < n:
                break
            self._emit(bytes(b[:n]), now, True)
            del b[:n]
        if flush and b:  # a partial frame that waited too long: pass it as it is
            self._emit(bytes(b), now, False)
            b.clear()
        self.buf_at = now

    def due(self, now):
        """Bytes whose time has come; stale partial frames are flushed first."""
        if self.buf and now - self.buf_at > 0.02:
            self._split(now, flush=True)
        ready = b""
        while self.out and self.out[0][0] <= now:
            ready += self.out.pop(0)[1]
        return ready

    def clear(self):
        self.buf.clear()
        self.out.clear()


def _write_all(fd, data, timeout=1.0):
    """A line does not lose bytes because the reader is slow: wait for room (a starved reader), up to timeout."""
    deadline = time.monotonic() + timeout
    while data:
        try:
            data = data[os.write(fd, data):]
        except BlockingIOError:
            if time.monotonic() > deadline:
                return
            select.select([], [fd], [], 0.01)


STALL_S = 0.5
NO_FAULTS = {"corrupt": 0.0, "drop": 0.0, "duplicate": 0.0, "delay_rate": 0.0, "delay_ms": 0.0}


class LineProxy:
    """rbx1d opens link_path; the proxy forwards to target_path. vanish()/reappear() unplug and replug the host's
    side, set_cut() is an outage, frames_to_fw the (ns, TYPE) of each frame the host sent."""

    def __init__(self, target_path, link_path, rates=None, seed=1):
        rates = rates or NO_FAULTS
        self.target_path = target_path
        self.link_path = link_path
        rng = random.Random(seed)
        self.to_fw = Direction("to_fw", rates, random.Random(rng.random()))
        self.to_host = Direction("to_host", rates, random.Random(rng.random()))
        self.lock = threading.Lock()
        self.cut = False
        self.master = None
        self.target = None
        self.target_reopens = 0
        self.stalls = []  # (start_ns, end_ns) of each pause over STALL_S between two turns of the loop
        self._stop = False
        self._open_target()
        self._open_side()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _open_target(self):
        try:
            fd = os.open(self.target_path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError:
            return False
        tty.setraw(fd)
        self.target = fd
        return True

    def _open_side(self):
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)
        name = os.ttyname(slave)
        os.close(slave)  # the daemon opens it by name; the master keeps the pty alive
        tmp = self.link_path + ".new"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(name, tmp)
        os.replace(tmp, self.link_path)
        with self.lock:
            self.master = master

    def vanish(self):
        with self.lock:
            m, self.master = self.master, None
            self.to_fw.clear()
            self.to_host.clear()
        if os.path.lexists(self.link_path):
            os.unlink(self.link_path)
        if m is not None:
            os.close(m)

    def reappear(self):
        self._open_side()

    def set_cut(self, cut):
        with self.lock:
            self.cut = cut
            if cut:
                self.to_fw.clear()
                self.to_host.clear()

    @property
    def frames_to_fw(self):
        with self.lock:
            return list(self.to_fw.seen)

    def counts(self):
        with self.lock:
            return {"to_fw": dict(self.to_fw.counts), "to_host": dict(self.to_host.counts)}

    def _target_gone(self):
        if self.target is not None:
            os.close(self.target)
            self.target = None
        self.to_fw.clear()
        self.to_host.clear()

    def _run(self):
        last = time.monotonic_ns()
        while not self._stop:
            # A proxy starved of CPU (a loaded machine) is a line that carries nothing: say so, as a fault of its own.
            now_ns = time.monotonic_ns()
            if now_ns - last > STALL_S * 1e9:
                with self.lock:
                    self.stalls.append((last, now_ns))
            last = now_ns
            with self.lock:
                m = self.master
            if self.target is None:
                if self._open_target():
                    self.target_reopens += 1
                else:
                    time.sleep(0.02)
                    continue
            fds = [self.target] + ([m] if m is not None else [])
            try:
                r, _, _ = select.select(fds, [], [], 0.002)
            except (OSError, ValueError):
                continue
            now = time.monotonic()
            for fd in r:
                try:
                    data = os.read(fd, 4096)
                except BlockingIOError:
                    continue
                except OSError:
                    if fd == self.target:
                        self._target_gone()  # the board hung up (power cycle): reopen its path when it is back
                        break
                    time.sleep(0.002)  # the daemon side is closed (between opens): wait for it
                    continue
                if not data:
                    if fd == self.target:
                        self._target_gone()
                        break
                    continue
                with self.lock:
                    if self.cut:
                        continue
                    (self.to_host if fd == self.target else self.to_fw).push(data, now)
            with self.lock:
                up, down, master = self.to_fw.due(now), self.to_host.due(now), self.master
            try:
                if up and self.target is not None:
                    _write_all(self.target, up)
            except OSError:
                self._target_gone()
            try:
                if down and master is not None:
                    _write_all(master, down)
            except OSError:
                pass

    def close(self):
        self._stop = True
        self.thread.join(timeout=1)
        self.vanish()
        if self.target is not None:
            os.close(self.target)
