"""test_client.py - the rbx1 client against small fake servers: the request lines it writes, events as an iterator
and a callback, error codes as exceptions, timeouts, the subscribe stream, the HTTP API's token header."""
import http.server
import json
import re
import socket
import sys
import threading
import time
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[2]
sys.path.insert(0, str(HERE.parent))
import rbx1  # noqa: E402


class FakeDaemon:
    """A Unix socket server: for each connection, reads one request line and answers with the lines that
    script(request) returns (each a dict, or a float: a pause in seconds); then closes unless hold is set."""

    def __init__(self, path, script, hold=False):
        self.path, self.script, self.hold = str(path), script, hold
        self.requests = []
        self.closed = threading.Event()  # a connection was closed by its client
        self.server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.server.bind(self.path)
        self.server.listen(8)
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                conn, _ = self.server.accept()
            except OSError:
                return
            threading.Thread(target=self._answer, args=(conn,), daemon=True).start()

    def _answer(self, conn):
        with conn:
            buf = b""
            while b"\n" not in buf:
                chunk = conn.recv(4096)
                if not chunk:
                    return
                buf += chunk
            request = json.loads(buf.split(b"\n")[0])
            self.requests.append(request)
            try:
                for line in self.script(request):
                    if isinstance(line, float):
                        time.sleep(line)
                    else:
                        conn.sendall(json.dumps(line).encode() + b"\n")
                if self.hold:
                    while conn.recv(4096):
                        pass
                    self.closed.set()
            except OSError:
                self.closed.set()

    def close(self):
        self.server.close()


@pytest.fixture
def fake(tmp_path):
    made = []

    def make(script, hold=False):
        made.append(FakeDaemon(tmp_path / "rbx1d.sock", script, hold))
        return made[-1]

    yield make
    for f in made:
        f.close()


def event(kind, **fields):
    return {"ts": "2026-12-02T06:00:00.000Z", "t_ms": 1.0, "event": kind, **fields}


def test_pick_writes_the_request_and_returns_the_result(fake):
    f = fake(lambda r: [event("job_started"), event("step_done", name="carry"), {"result": {"picked": r["name"]}}])
    arm = rbx1.Arm(socket=f.path)
    seen = []
    assert arm.pick("bolt", "tray", on_event=seen.append) == {"picked": "bolt"}
    assert f.requests == [{"cmd": "pick", "name": "bolt", "place": "tray"}]
    assert [e["event"] for e in seen] == ["job_started", "step_done"]


def test_events_as_an_iterator_as_they_come(fake):
    f = fake(lambda r: [event("job_started"), 0.3, event("step"), 0.3, {"result": {"position": [0] * 6}}])
    job = rbx1.Arm(socket=f.path).start("home")
    t0 = time.monotonic()
    first = next(iter(job))
    assert first["event"] == "job_started" and time.monotonic() - t0 < 0.25  # not held back until the end
    assert [e["event"] for e in job] == ["step"]
    assert job.result() == {"position": [0] * 6}
    assert [e["event"] for e in job.events] == ["job_started", "step"]


def test_optional_fields_are_left_out_and_every_request_is_reachable(fake):
    f = fake(lambda r: [{"result": {}}])
    arm = rbx1.Arm(socket=f.path)
    arm.jog(joint=2, steps=100)
    arm.jog(mm=(1.0, 0, -2.5))
    arm.background()
    arm.teach(3, "nut")
    arm.calibrate_workspace("record", marker=7)
    arm.sort({"bolt": "tray"}, max_picks=2)
    arm.clear("tray")
    arm.history(limit=5)
    arm.request("conveyor", speed=3)  # a request this client has no method for
    assert f.requests == [
        {"cmd": "jog", "joint": 2, "steps": 100}, {"cmd": "jog", "mm": [1.0, 0, -2.5]}, {"cmd": "background"},
        {"cmd": "teach", "index": 3, "name": "nut"}, {"cmd": "calibrate_workspace", "action": "record", "marker": 7},
        {"cmd": "sort", "recipe": {"bolt": "tray"}, "max_picks": 2}, {"cmd": "clear", "place": "tray"},
        {"cmd": "history", "limit": 5}, {"cmd": "conveyor", "speed": 3}]


@pytest.mark.parametrize("code, cls", [("object_absent", rbx1.ObjectAbsent), ("not_ready", rbx1.NotReady),
                                       ("busy", rbx1.Busy), ("estop_active", rbx1.EstopActive),
                                       ("estop", rbx1.Estop), ("bad_field", rbx1.BadField),
                                       ("timeout", rbx1.Timeout), ("link_down", rbx1.LinkDown)])
def test_error_codes_raise_their_class_with_the_daemons_message(fake, code, cls):
    f = fake(lambda r: [event("job_started"), {"error": {"code": code, "message": "why it failed"}}])
    with pytest.raises(cls) as e:
        rbx1.Arm(socket=f.path).pick("bolt", "tray")
    assert isinstance(e.value, rbx1.Rbx1Error)
    assert e.value.code == code and e.value.message == "why it failed"
    assert e.value.reply == {"error": {"code": code, "message": "why it failed"}}


def test_an_unknown_code_is_the_base_class_with_its_code(fake):
    f = fake(lambda r: [{"error": {"code": "conveyor_jammed", "message": "belt 2"}}])
    with pytest.raises(rbx1.Rbx1Error) as e:
        rbx1.Arm(socket=f.path).home()
    assert type(e.value) is rbx1.Rbx1Error and e.value.code == "conveyor_jammed" and e.value.message == "belt 2"


def test_request_errors_share_a_base(fake):
    f = fake(lambda r: [{"error": {"code": "missing_field", "message": "pick needs \"place\""}}])
    with pytest.raises(rbx1.RequestError):
        rbx1.Arm(socket=f.path).request("pick", name="bolt")


# The client's own codes: failures on this side of the socket, never in a reply.
CLIENT_CODES = {"no_reply", "disconnected"}
# An error code written as a string where a reply is made, as it was before the one list (a mistyped code then went
# out unseen): error("busy", ...), error_json("busy", ...), refuse(to, "stale", ...), code = "degenerate", ...
WRITTEN = re.compile(r'(?:\.error\(|->error\(|fail\(|error_json\(|refuse\([^,;]*,|code = |error = \{|abort_reason_ = )'
                     r'\s*"([a-z_]+)"')
CHOSEN = re.compile(r'error\([^;"]*\?\s*"([a-z_]+)"\s*:\s*"([a-z_]+)"')  # error(held ? "estop_active" : "fault"


def listed_codes():
    """The one list (host/daemon/error_codes.hpp), as the README's table and rbx1 commands --json show it."""
    return set(re.findall(r'X\(\w+,\s*"([a-z_]+)"', (ROOT / "host" / "daemon" / "error_codes.hpp").read_text()))


def test_the_list_and_the_exceptions_match():
    listed = listed_codes()
    assert {"busy", "object_absent", "estop_active", "unauthorized", "degenerate", "stale"} <= listed, listed
    missing = sorted(listed - set(rbx1.CODES))
    assert not missing, f"error codes without a class in host/python/rbx1/errors.py: {missing}"
    unlisted = sorted(set(rbx1.CODES) - listed - CLIENT_CODES)
    assert not unlisted, f"classes in host/python/rbx1/errors.py for codes the list lacks: {unlisted}"


def test_no_error_code_is_written_as_a_string():
    """Replies take their code from the list (ErrorCode): the daemon, the console and MQTT write none as a string
    (the CLI's own messages in host/cli are not replies)."""
    assert WRITTEN.findall('reply.error("busy", why); refuse(to, "stale", why); code = "degenerate";') == \
        ["busy", "stale", "degenerate"]  # the grep works
    assert CHOSEN.findall('error(held ? "estop_active" : "fault", m)') == [("estop_active", "fault")]
    found = []
    for path in sorted((ROOT / "host").rglob("*.[ch]pp")):
        if path.parent.name != "cli" and not path.name.endswith("_test.cpp"):
            text = path.read_text(errors="replace")
            found += [f"{path.relative_to(ROOT)}: {c}" for c in WRITTEN.findall(text) + CHOSEN.findall(text)]
    assert not found, f"error codes written as strings (use ErrorCode, error_codes.hpp): {found}"


def test_no_reply_within_the_timeout(fake):
    f = fake(lambda r: [event("job_started"), 2.0, {"result": {}}])
    t0 = time.monotonic()
    with pytest.raises(rbx1.NoReply) as e:
        rbx1.Arm(socket=f.path, timeout=0.3).status()
    assert 0.25 < time.monotonic() - t0 < 1.5
    assert isinstance(e.value, TimeoutError)


def test_jobs_wait_without_a_limit_by_default_and_take_their_own(fake):
    f = fake(lambda r: [event("job_started"), 0.6, {"result": {"ok": True}}])
    arm = rbx1.Arm(socket=f.path, timeout=0.2)
    assert arm.home() == {"ok": True}  # a job: job_timeout (None), not timeout
    with pytest.raises(rbx1.NoReply):
        arm.home(timeout=0.2)


def test_a_connection_closed_before_the_final_line(fake, tmp_path):
    f = fake(lambda r: [event("job_started")])
    job = rbx1.Arm(socket=f.path).start("pick", name="bolt", place="tray")
    with pytest.raises(rbx1.Disconnected):
        job.result()
    assert [e["event"] for e in job.events] == ["job_started"]
    with pytest.raises(rbx1.Disconnected) as e:
        rbx1.Arm(socket=str(tmp_path / "nobody.sock")).status()
    assert "nobody.sock" in e.value.message


def test_closing_a_job_closes_its_connection(fake):
    f = fake(lambda r: [event("step")], hold=True)
    job = rbx1.Arm(socket=f.path).start("jog", joint=1, deg=10)
    assert next(iter(job))["event"] == "step"
    job.close()
    assert f.closed.wait(2), "the connection stayed open after close()"


def test_socket_from_the_environment(fake, monkeypatch):
    f = fake(lambda r: [{"result": {"ready": True}}])
    monkeypatch.setenv("RBX1_SOCKET", f.path)
    assert rbx1.Arm().status() == {"ready": True}
    monkeypatch.delenv("RBX1_SOCKET")
    assert rbx1.Arm().socket == rbx1.DEFAULT_SOCKET


def test_watch_subscribes_and_iterates_the_stream(fake):
    msgs = [{"topic": "status", "seq": i, "ready": True} for i in range(3)]
    f = fake(lambda r: msgs, hold=True)
    with rbx1.Arm(socket=f.path).watch(topics=("status",)) as w:
        got = []
        for m in w:
            got.append(m)
            if len(got) == 3:
                break
    assert f.requests == [{"cmd": "subscribe", "topics": ["status"]}]
    assert got == msgs
    assert f.closed.wait(2)


def test_watch_raises_an_error_reply(fake):
    f = fake(lambda r: [{"error": {"code": "unknown_command", "message": "unknown command \"subscribe\""}}])
    with pytest.raises(rbx1.UnknownCommand):
        list(rbx1.Arm(socket=f.path).watch())


# ---- the HTTP API ----------------------------------------------------------------------------------------------

class FakeConsole(http.server.BaseHTTPRequestHandler):
    """Answers as console.cpp does: a token is needed for POSTs; the reply carries its events."""
    token = "s3cret-token-0123456789"
    seen = []
    stream = []  # the lines of GET /api/events (the console fixture sets them)

    def log_message(self, *args):
        pass

    def reply(self, status, body):
        data = json.dumps(body).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def do_GET(self):
        self.seen.append(("GET", self.path, self.headers.get("Authorization"), None))
        if self.path == "/api/status":
            return self.reply(200, {"result": {"ready": True}, "events": []})
        if self.path == "/api/events":
            self.send_response(200)
            self.send_header("Content-Type", "text/event-stream")
            self.end_headers()
            for i, line in enumerate(self.stream):
                self.wfile.write(f"id: {i + 1}\ndata: {json.dumps(line)}\n\n".encode())
            self.wfile.write(b": keep-alive\n\n")
            self.wfile.flush()
            return
        self.reply(404, {"error": {"code": "not_found", "message": "no such page"}})

    def do_POST(self):
        body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
        self.seen.append(("POST", self.path, self.headers.get("Authorization"), body))
        if self.headers.get("Content-Type") != "application/json":
            return self.reply(415, {"error": {"code": "bad_request", "message": "not JSON"}})
        if self.headers.get("Authorization") != "Bearer " + self.token:
            return self.reply(401, {"error": {"code": "unauthorized", "message": "wrong console token"}})
        if self.path == "/api/sort":  # answered when it started, as console.cpp does
            return self.reply(202, {"started": event("sort_started", job=3), "req": 7, "events": [event("sort_started", job=3)]})
        if self.path == "/api/pick" and body.get("name") == "unicorn":
            absent = {"code": "object_absent", "message": "object \"unicorn\" is not in the scene"}
            return self.reply(409, {"error": absent, "events": [event("absent")]})
        self.reply(200, {"result": {"done": self.path}, "events": [event("job_started"), event("step_done")]})


@pytest.fixture
def console():
    FakeConsole.seen = []
    FakeConsole.stream = [{"req": 1, "event": "step", "n": i} for i in range(2)]
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), FakeConsole)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def test_http_sends_the_bearer_token_and_the_fields(console):
    arm = rbx1.Arm(url=console, token=FakeConsole.token)
    seen = []
    assert arm.pick("bolt", "tray", on_event=seen.append) == {"done": "/api/pick"}
    assert [e["event"] for e in seen] == ["job_started", "step_done"]
    assert arm.status() == {"ready": True}
    assert FakeConsole.seen == [("POST", "/api/pick", "Bearer " + FakeConsole.token, {"name": "bolt", "place": "tray"}),
                                ("GET", "/api/status", "Bearer " + FakeConsole.token, None)]


def test_http_a_sort_answered_when_it_started_is_followed_on_the_event_stream(console):
    """The console answers a sort 202 when it started; the client reads its later lines (req 7) from the event stream,
    after the replayed ones up to its start, to its final line."""
    later = {"ts": "2026-12-02T06:00:01.000Z", "t_ms": 1000.0}
    FakeConsole.stream = [{"req": 6, "cmd": "scan", "result": {}, "final": True},
                          {"req": 7, "cmd": "sort", "request": {"cmd": "sort"}},
                          {"req": 7, "cmd": "sort", **event("sort_started", job=3)},
                          {"req": 8, "cmd": "status", "event": "other"},
                          {"req": 7, "cmd": "sort", **later, "event": "progress", "phase": "pick", "picked": 0},
                          {"req": 7, "cmd": "sort", "result": {"job": 3, "outcome": "done"}, "final": True}]
    seen = []
    result = rbx1.Arm(url=console, token=FakeConsole.token).sort({"bolt": "tray"}, on_event=seen.append)
    assert result == {"job": 3, "outcome": "done"}
    assert [e["event"] for e in seen] == ["sort_started", "progress"]


def test_http_errors_raise_their_class(console):
    with pytest.raises(rbx1.Unauthorized) as e:
        rbx1.Arm(url=console, token="wrong").home()
    assert e.value.message == "wrong console token"
    with pytest.raises(rbx1.Unauthorized):
        rbx1.Arm(url=console).home()  # no token: no header
    assert FakeConsole.seen[-1][2] is None
    with pytest.raises(rbx1.ObjectAbsent) as e:
        rbx1.Arm(url=console, token=FakeConsole.token).pick("unicorn", "tray")
    assert e.value.reply["events"][0]["event"] == "absent"


def test_http_watch_reads_the_event_stream(console):
    w = rbx1.Arm(url=console).watch()
    got = []
    for m in w:
        got.append(m)
        if len(got) == 2:
            break
    w.close()
    assert [m["n"] for m in got] == [0, 1]


def test_http_unreachable(tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # closed again: nobody listens there
    with pytest.raises(rbx1.Disconnected):
        rbx1.Arm(url=f"http://127.0.0.1:{port}").status()


def test_the_readme_table_names_every_exception():
    """host/python/README.md's table of classes names every class of errors.py (a script's author reads it there)."""
    readme = (ROOT / "host" / "python" / "README.md").read_text()
    table = readme[readme.index("| class | code |"):].split("\n\n")[0]
    named = set(re.findall(r"`(\w+)`", table))
    classes = re.findall(r"^class (\w+)\(", (ROOT / "host" / "python" / "rbx1" / "errors.py").read_text(), re.M)
    missing = [c for c in classes if c not in named and c != "Rbx1Error"]
    assert not missing, f"exception classes missing from host/python/README.md's table: {missing}"
