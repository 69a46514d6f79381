"""test_bus.py - the daemon's bus seen from outside: a subscriber on the control socket sees a pick started by
another client (the CLI) line for line, and the status changes it makes; `rbx1 watch` prints them; ten subscribers
that never read stall neither the pick nor the e-stop."""
import json
import socket
import subprocess
import threading
import time

import rbx1e2e as e2e

IGNORED = {"topic", "seq", "req", "cmd", "missed", "final"}


class Subscriber:
    """A raw subscribe connection whose lines a thread collects."""

    def __init__(self, sock_path, topics=("status", "events", "scans"), read=True):
        self.s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.s.connect(sock_path)
        self.s.sendall((json.dumps({"cmd": "subscribe", "topics": list(topics)}) + "\n").encode())
        self.lines, self.lock = [], threading.Lock()
        if read:
            threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        buf = b""
        while True:
            try:
                chunk = self.s.recv(65536)
            except OSError:
                return
            if not chunk:
                return
            buf += chunk
            while b"\n" in buf:
                raw, buf = buf.split(b"\n", 1)
                with self.lock:
                    self.lines.append(json.loads(raw))

    def wait(self, pred, timeout=30):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                if pred(self.lines):
                    return list(self.lines)
            time.sleep(0.05)
        with self.lock:
            raise AssertionError(f"not seen within {timeout} s; last lines: {self.lines[-5:]}")

    def close(self):
        self.s.close()


def test_a_subscriber_sees_a_cli_pick_whole_and_the_status_it_changes(sim, daemon_factory):
    d = daemon_factory(sim.port)
    sub = Subscriber(d.socket)
    sub.wait(lambda ls: any(l.get("topic") == "status" for l in ls))
    cli = subprocess.run([e2e.need(e2e.BIN / "rbx1"), "pick", "l_shape", "--place", "tray", "--json",
                          "--socket", d.socket], capture_output=True, text=True, timeout=180)
    assert cli.returncode == 0, cli.stderr
    # The bus adds topic, seq, req, cmd (job_started has the request's cmd too), missed and final to each line.
    cli_lines = [{k: v for k, v in json.loads(l).items() if k not in IGNORED} for l in cli.stdout.splitlines()]
    lines = sub.wait(lambda ls: any(l.get("topic") == "events" and l.get("final") for l in ls))
    events = [l for l in lines if l.get("topic") == "events"]
    req = events[0]["req"]
    assert events[0]["request"] == {"cmd": "pick", "name": "l_shape", "place": "tray"}, events[0]
    mine = [{k: v for k, v in l.items() if k not in IGNORED} for l in events[1:] if l["req"] == req]
    assert mine == cli_lines, (len(mine), len(cli_lines))
    assert all(l.get("missed", 0) == 0 for l in lines), "a reading subscriber lost lines"
    # The status went from idle to the pick and back, with the joints moving in between.
    jobs = [l["job"] for l in lines if l.get("topic") == "status"]
    assert "pick" in jobs and jobs[-1] is None or sub.wait(
        lambda ls: [l for l in ls if l.get("topic") == "status"][-1]["job"] is None), jobs
    moving = {tuple(l["joints_deg"]) for l in lines if l.get("topic") == "status" and l["job"] == "pick"}
    assert len(moving) > 3, "status lines while moving should show the joints changing"
    scans = [l for l in lines if l.get("topic") == "scans"]
    assert len(scans) == 1 and len(scans[0]["detections"]["objects"]) == 5, scans
    sub.close()


def test_watch_prints_readable_lines(sim, daemon_factory):
    d = daemon_factory(sim.port)
    watch = subprocess.Popen([e2e.need(e2e.BIN / "rbx1"), "watch", "--topics", "status,events", "--socket", d.socket],
                             stdout=subprocess.PIPE, text=True)
    lines = []

    def read():
        for line in watch.stdout:
            lines.append(line)

    reader = threading.Thread(target=read, daemon=True)

    def seen(text, timeout=60):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not any(text in line for line in lines):
            time.sleep(0.05)
        return any(text in line for line in lines)

    reader.start()
    try:
        assert seen("status  "), "no status line: the subscription never started"  # the last status comes first
        assert "result" in d.request({"cmd": "home"})[1]
        assert seen("home  result"), lines
    finally:
        watch.terminate()
        watch.wait(timeout=10)
    out = "".join(lines)
    assert "events  #" in out and "home  request" in out and "home  result" in out, out


def test_subscribers_that_never_read_stall_neither_the_pick_nor_the_estop(sim, daemon_factory):
    d = daemon_factory(sim.port)
    idle = [Subscriber(d.socket, read=False) for _ in range(10)]
    events, final = d.request({"cmd": "pick", "name": "l_shape", "place": "tray"}, timeout=180)
    assert "result" in final, final
    t0 = time.monotonic()
    events, final = d.request({"cmd": "estop"}, timeout=10)
    assert final["result"]["estop"] is True
    assert time.monotonic() - t0 < 5
    # The daemon still answers everyone, and a new subscriber is served.
    sub = Subscriber(d.socket, topics=("status",))
    sub.wait(lambda ls: any(l.get("topic") == "status" and l.get("last_estop") == "control" for l in ls))
    for s in idle + [sub]:
        s.close()


def test_the_console_log_shows_a_cli_job(sim, daemon_factory):
    """The console's event log follows the bus: a job started from the CLI is in it, request to result."""
    import urllib.request
    d = daemon_factory(sim.port)
    url = d.console_url()
    cli = subprocess.run([e2e.need(e2e.BIN / "rbx1"), "home", "--socket", d.socket], capture_output=True, text=True,
                         timeout=120)
    assert cli.returncode == 0, cli.stderr
    seen, deadline = [], time.monotonic() + 20
    with urllib.request.urlopen(url.rstrip("/") + "/api/events", timeout=20) as r:
        while time.monotonic() < deadline:
            line = r.readline().decode()
            if line.startswith("data:"):
                e = json.loads(line[5:])
                if e.get("cmd") == "home":
                    seen.append("request" if "request" in e else "result" if "result" in e else e.get("event"))
                    if "result" in e:
                        break
    assert seen[0] == "request" and "job_started" in seen and seen[-1] == "result", seen
