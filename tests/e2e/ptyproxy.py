"""ptyproxy.py - a byte forwarder between a pty the daemon opens (through a symlink) and the simulator's pty.

It can cut the line (hold every byte: a link outage), make the port vanish (close the pty and remove the symlink,
as when the USB device is unplugged) and bring it back, and it timestamps the frames it forwards (CLOCK_MONOTONIC
ns) so that benches see when a message was on the wire.
"""
import os
import select
import threading
import time
import tty

SYNC = 0xA5


class PtyProxy:
    def __init__(self, target_path, link_path):
        self.target_path = target_path
        self.link_path = link_path
        self.target = os.open(target_path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.target)
        self.lock = threading.Lock()
        self.cut = False          # outage: bytes are dropped both ways
        self.master = None
        self.frames_to_fw = []    # (mono_ns, type) of each frame start seen host -> firmware
        self._scan = bytearray()
        self._stop = False
        self._open_side()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

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
        """The device disappears: the daemon's fd hangs up and the path is gone."""
        with self.lock:
            m, self.master = self.master, None
        if os.path.lexists(self.link_path):
            os.unlink(self.link_path)
        if m is not None:
            os.close(m)

    def reappear(self):
        self._open_side()

    def set_cut(self, cut):
        with self.lock:
            self.cut = cut

    def _note(self, data):
        """Frame starts host -> firmware: SYNC, LEN, SEQ, TYPE; a cheap scan good enough for timing."""
        now = time.monotonic_ns()
        self._scan += data
        while len(self._scan) >= 4:
            if self._scan[0] != SYNC:
                del self._scan[0]
                continue
            ln = self._scan[1]
            if ln > 58:
                del self._scan[0]
                continue
            if len(self._scan) < ln + 6:
                break
            self.frames_to_fw.append((now, self._scan[3]))
            del self._scan[: ln + 6]

    def _run(self):
        while not self._stop:
            with self.lock:
                m = self.master
            fds = [self.target] + ([m] if m is not None else [])
            try:
                r, _, _ = select.select(fds, [], [], 0.02)
            except (OSError, ValueError):
                continue
            for fd in r:
                try:
                    data = os.read(fd, 4096)
                except OSError:
                    time.sleep(0.005)  # the daemon side is closed (between opens): wait for it
                    continue
                if not data:
                    continue
                with self.lock:
                    cut, master = self.cut, self.master
                if cut:
                    continue
                try:
                    if fd == self.target:
                        if master is not None:
                            os.write(master, data)
                    else:
                        self._note(data)
                        os.write(self.target, data)
                except OSError:
                    pass

    def close(self):
        self._stop = True
        self.thread.join(timeout=1)
        self.vanish()
        os.close(self.target)
