"""arm.py - Arm: every request of rbx1d, over its control socket or the web console's HTTP API; Job: one reply."""
import os

from . import console_http, control_socket
from .errors import Disconnected, error_from

DEFAULT_SOCKET = "/run/rbx1/rbx1d.sock"

# Requests answered at once (the CLI waits 10 s for these); the rest move the arm and wait for it.
SHORT_REQUESTS = frozenset({"status", "estop", "shutdown", "history"})

_DEFAULT = object()


def _is_final(line):
    return "result" in line or "error" in line


class Job:
    """One request's reply: iterate it for the event lines as they come; result() for the result, or the error
    raised as its exception. The lines read are kept: .events, then .final (the raw final line)."""

    def __init__(self, lines, on_event=None):
        self._lines = lines
        self._on_event = on_event
        self.events = []
        self.final = None

    def __iter__(self):
        while self.final is None:
            try:
                line = next(self._lines)
            except StopIteration:
                raise Disconnected("the reply ended without a final line") from None
            if _is_final(line):
                self.final = line
                self._lines.close()
                return
            self.events.append(line)
            if self._on_event:
                self._on_event(line)
            yield line

    def wait(self):
        """Reads up to the final line and returns it as it came ({"result": ...} or {"error": ...})."""
        for _ in self:
            pass
        return self.final

    def result(self):
        """The request's result; an error reply raises its exception (rbx1.ObjectAbsent, rbx1.Busy, ...)."""
        final = self.wait()
        if "error" in final:
            raise error_from(final)
        return final["result"]

    def close(self):
        """Stops reading and closes the connection (a jog whose client goes away stops: the dead-man rule)."""
        self._lines.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class Watch:
    """The daemon's bus as an iterator of messages (each with "topic" and "seq"), until close()."""

    def __init__(self, lines):
        self._lines = lines

    def __iter__(self):
        for line in self._lines:
            if "error" in line:
                raise error_from(line)
            if "result" in line and "topic" not in line:
                continue  # an acknowledgement, not a message
            yield line

    def close(self):
        self._lines.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class Arm:
    """A client of rbx1d. Arm(socket=PATH) speaks the control socket (default $RBX1_SOCKET, else
    /run/rbx1/rbx1d.sock); Arm(url="http://127.0.0.1:8080", token=...) the web console's HTTP API. timeout: the
    longest wait in seconds for the next reply line of status, estop, shutdown and history; job_timeout: the same
    for requests that move the arm (None: no limit; the daemon has its own job limits). Each request has its own
    connection, so one Arm may be used from several threads (an estop while a pick runs)."""

    def __init__(self, socket=None, url=None, token=None, timeout=10.0, job_timeout=None):
        if socket and url:
            raise ValueError("Arm takes socket= or url=, not both")
        self.url = url
        self.token = token
        self.socket = None if url else (socket or os.environ.get("RBX1_SOCKET") or DEFAULT_SOCKET)
        self.timeout = timeout
        self.job_timeout = job_timeout

    def __repr__(self):
        return f"Arm(url={self.url!r})" if self.url else f"Arm(socket={self.socket!r})"

    # ---- requests ------------------------------------------------------------------------------------------------

    def send(self, request, timeout=_DEFAULT, on_event=None):
        """Sends one request (a dict, or over the socket a raw line) and returns its Job, unread."""
        cmd = request.get("cmd") if isinstance(request, dict) else None
        if timeout is _DEFAULT:
            timeout = self.timeout if cmd in SHORT_REQUESTS else self.job_timeout
        if self.url:
            lines = console_http.lines(self.url, self.token, request, timeout)
        else:
            lines = control_socket.lines(self.socket, request, timeout)
        return Job(lines, on_event)

    def start(self, cmd, *, timeout=_DEFAULT, on_event=None, **fields):
        """Sends {"cmd": cmd, **fields}; returns the Job to iterate for its events."""
        return self.send({"cmd": cmd, **fields}, timeout, on_event)

    def request(self, cmd, *, timeout=_DEFAULT, on_event=None, **fields):
        """Any request of the daemon's command table: {"cmd": cmd, **fields}; returns its result or raises its error.
        on_event(event) is called for each event line (over HTTP: all at the end)."""
        return self.start(cmd, timeout=timeout, on_event=on_event, **fields).result()

    def _call(self, cmd, kw, **fields):
        return self.request(cmd, **kw, **{k: v for k, v in fields.items() if v is not None})

    def status(self, **kw):
        return self._call("status", kw)

    def scan(self, **kw):
        """Moves to the scan pose, captures, detects; result: objects, report, detections."""
        return self._call("scan", kw)

    def pick(self, name, place, **kw):
        return self._call("pick", kw, name=name, place=place)

    def home(self, **kw):
        return self._call("home", kw)

    def estop(self, **kw):
        return self._call("estop", kw)

    def clear_fault(self, **kw):
        return self._call("clear_fault", kw)

    def shutdown(self, **kw):
        return self._call("shutdown", kw)

    def jog(self, joint=None, steps=None, deg=None, mm=None, **kw):
        """A joint (1..6) by steps or deg, or the tool point by mm=[dx, dy, dz] in the base frame."""
        return self._call("jog", kw, joint=joint, steps=steps, deg=deg, mm=None if mm is None else list(mm))

    def pose_save(self, name="scan", **kw):
        return self._call("pose_save", kw, name=name)

    def place_save(self, name, **kw):
        return self._call("place_save", kw, name=name)

    def background(self, frames=None, **kw):
        return self._call("background", kw, frames=frames)

    def teach(self, index, name, mirror_ok=None, **kw):
        """Teaches object number index of the live scan as name."""
        return self._call("teach", kw, index=index, name=name, mirror_ok=mirror_ok)

    def calibrate_workspace(self, action, marker=None, **kw):
        """action: start, status, record (with marker), fit, save, cancel."""
        return self._call("calibrate_workspace", kw, action=action, marker=marker)

    def sort(self, recipe, max_picks=None, **kw):
        """recipe: {"CLASS": "PLACE", ...} or a saved recipe's name."""
        return self._call("sort", kw, recipe=recipe, max_picks=max_picks)

    def clear(self, place, **kw):
        return self._call("clear", kw, place=place)

    def history(self, limit=None, **kw):
        """Result: jobs, picks (one row per pick attempt)."""
        return self._call("history", kw, limit=limit)

    # ---- the bus -------------------------------------------------------------------------------------------------

    def watch(self, topics=("status", "events", "scans"), timeout=None):
        """The daemon's bus (subscribe) as an iterator of messages until close(). Over HTTP: the console's event
        log (GET /api/events; topics do not apply)."""
        if self.url:
            return Watch(console_http.events(self.url, self.token, timeout))
        return Watch(control_socket.lines(self.socket, {"cmd": "subscribe", "topics": list(topics)}, timeout))
