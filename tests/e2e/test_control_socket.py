"""test_control_socket.py - rbx1d's control socket under abuse: a client that writes and never reads, 100 idle and
10 flooding connections, idle connections timing out; `rbx1 status` and `rbx1 estop` still get through and the
e-stop reaches the firmware."""
import socket
import subprocess
import threading
import time

import rbx1e2e as e2e
from conftest import fast_config

BURST = b'{"cmd":"status"}\n' * 64


class Flooder(threading.Thread):
    """Writes status requests as fast as the socket takes them and never reads; counts the daemon's drops and
    connects again when asked."""

    def __init__(self, path, reconnect):
        super().__init__(daemon=True)
        self.path, self.reconnect = path, reconnect
        self.sent = self.drops = 0
        self.stop = threading.Event()
        self.start()

    def run(self):
        while not self.stop.is_set():
            s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            s.settimeout(0.05)
            try:
                s.connect(self.path)
            except OSError:
                s.close()
                time.sleep(0.01)
                continue
            try:
                while not self.stop.is_set():
                    try:
                        self.sent += s.send(BURST)
                    except socket.timeout:
                        continue
            except OSError:  # BrokenPipe, ConnectionReset: the daemon dropped us
                self.drops += 1
            s.close()
            if not self.reconnect:
                self.stop.wait()

    def finish(self):
        self.stop.set()
        self.join(timeout=5)


def cli(d, *args):
    t0 = time.monotonic()
    r = subprocess.run([e2e.need(e2e.BIN / "rbx1"), *args, "--socket", d.socket], capture_output=True, text=True,
                       timeout=30)
    return r, (time.monotonic() - t0) * 1000


def firmware_state(d):
    _, final = d.request({"cmd": "status"}, timeout=10)
    return final["result"]["firmware"]


def test_a_client_that_never_reads_stalls_nobody(sim, daemon_factory):
    d = daemon_factory(sim.port)
    f = Flooder(d.socket, reconnect=False)
    try:
        deadline = time.monotonic() + 10
        while f.drops == 0 and time.monotonic() < deadline:
            r, ms = cli(d, "status", "--json")
            assert r.returncode == 0, f"rbx1 status beside a client that never reads: {r.stderr}"
        assert f.drops == 1, f"the client that never reads was not disconnected (sent {f.sent} B)"
        r, ms = cli(d, "estop")
        assert r.returncode == 0, r.stderr
        fw = firmware_state(d)
        assert fw["state"] == "FAULT" and "ESTOP_COMMAND" in fw["faults"], fw
        assert "disconnected: its replies are not read" in d.log_path.read_text()
    finally:
        f.finish()


def test_estop_gets_through_100_idle_and_10_flooding_clients(sim, daemon_factory):
    d = daemon_factory(sim.port)
    idle = []
    flooders = []
    try:
        for _ in range(100):
            s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            s.connect(d.socket)
            idle.append(s)
        flooders = [Flooder(d.socket, reconnect=True) for _ in range(10)]
        deadline = time.monotonic() + 5
        while sum(f.sent for f in flooders) < 2_000_000 and time.monotonic() < deadline:
            time.sleep(0.05)
        r, status_ms = cli(d, "status")
        assert r.returncode == 0, r.stderr
        r, estop_ms = cli(d, "estop", "--json")
        assert r.returncode == 0, r.stderr
        assert '"estop": true' in r.stdout or '"estop":true' in r.stdout, r.stdout
        fw = firmware_state(d)
        assert fw["state"] == "FAULT" and "ESTOP_COMMAND" in fw["faults"], fw
        assert sum(f.drops for f in flooders) > 0, "no flooding client was ever dropped"
        print(f"rbx1 status {status_ms:.0f} ms, rbx1 estop {estop_ms:.0f} ms (whole CLI process) with 100 idle and "
              f"10 flooding clients; flooders sent {sum(f.sent for f in flooders)} B, dropped "
              f"{sum(f.drops for f in flooders)} times")
    finally:
        for f in flooders:
            f.finish()
        for s in idle:
            s.close()


def test_idle_connections_time_out(sim, daemon_factory):
    cfg = fast_config()
    cfg["daemon"]["idle_timeout_s"] = 0.5
    d = daemon_factory(sim.port, cfg)
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.connect(d.socket)
    s.settimeout(5)
    t0 = time.monotonic()
    assert s.recv(100) == b"", "the daemon sent something to an idle connection"
    waited = time.monotonic() - t0
    s.close()
    assert 0.4 <= waited < 4, waited
    # A request that takes longer than the idle timeout keeps its connection (scan: the arm moves to the scan pose).
    events, final = d.request({"cmd": "scan"}, timeout=30)
    assert "result" in final, final
    assert events[-1]["t_ms"] > 500, "the scan was too short to show anything"
