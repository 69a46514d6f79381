"""console_http.py - the web console's HTTP API (POST /api/CMD, GET /api/status, GET /api/events) as reply lines."""
import json
import socket
import urllib.error
import urllib.request

from .errors import Disconnected, NoReply, Rbx1Error


def _open(url, token, body, timeout):
    """The response of GET (body None) or POST (body: a dict sent as JSON); an HTTP error's response too."""
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, method="GET" if data is None else "POST")
    if data is not None:
        req.add_header("Content-Type", "application/json")
    if token:
        req.add_header("Authorization", "Bearer " + token)
    try:
        return urllib.request.urlopen(req, timeout=timeout)
    except urllib.error.HTTPError as e:
        return e  # 4xx/5xx carry the same {"error": ...} body
    except (socket.timeout, TimeoutError) as e:
        raise NoReply(f"no reply from the console at {url} within {timeout} s") from e
    except urllib.error.URLError as e:
        if isinstance(e.reason, (socket.timeout, TimeoutError)):
            raise NoReply(f"no reply from the console at {url} within {timeout} s") from e
        raise Disconnected(f"cannot reach the console at {url}: {e.reason}") from e


def _read_json(resp, url, timeout):
    try:
        text = resp.read()
    except (socket.timeout, TimeoutError) as e:
        raise NoReply(f"no reply from the console at {url} within {timeout} s") from e
    finally:
        resp.close()
    try:
        return json.loads(text)  # a jog's reply may lead with spaces (the dead-man's keep-alive): valid JSON
    except ValueError:
        status = getattr(resp, "status", None) or getattr(resp, "code", "?")
        raise Rbx1Error(f"HTTP {status} from {url}: not a JSON reply: {text[:200]!r}", code="bad_reply") from None


def lines(base_url, token, request, timeout):
    """One request through the console: yields its event lines, then the final line. The console answers when the
    request has ended, so the events all come at once, at the end; but a sort or clear is answered when it started
    (202 {"started", "req"}): its later lines are read from the event stream."""
    if not isinstance(request, dict) or not isinstance(request.get("cmd"), str):
        raise ValueError("the HTTP API takes a request as a dict with a \"cmd\"")
    fields = {k: v for k, v in request.items() if k != "cmd"}
    cmd = request["cmd"]
    url = f"{base_url.rstrip('/')}/api/{cmd}"
    get = cmd == "status" and not fields
    body = _read_json(_open(url, token, None if get else fields, timeout), url, timeout)
    for event in body.get("events") or []:
        yield event
    if "started" in body and "req" in body:
        yield from _follow(base_url, token, body["started"], body["req"], timeout)
    else:
        yield body


def _follow(base_url, token, started, req, timeout):
    """A long job's lines after its started line, from the event stream (whose replay of the last lines skipped up to
    that line), to its final line."""
    seen_start = False
    for line in events(base_url, token, timeout):
        if "req" not in line and "error" in line:  # the stream itself refused (token)
            yield line
            return
        if line.get("req") != req:
            continue
        if not seen_start:
            seen_start = line.get("event") == started.get("event") and line.get("ts") == started.get("ts")
            continue
        yield line
        if "result" in line or "error" in line:
            return


def events(base_url, token, timeout):
    """GET /api/events: each server-sent event's data as a dict, until the stream ends (the console replays its last
    lines first)."""
    url = f"{base_url.rstrip('/')}/api/events"
    resp = _open(url, token, None, timeout)
    if resp.status != 200:
        yield _read_json(resp, url, timeout)  # the error line: the caller raises it
        return
    try:
        data = []
        while True:
            try:
                raw = resp.readline()
            except (socket.timeout, TimeoutError) as e:
                raise NoReply(f"nothing from {url} within {timeout} s") from e
            if not raw:
                raise Disconnected(f"the console at {url} closed the event stream")
            line = raw.decode("utf-8", "replace").rstrip("\r\n")
            if line.startswith("data:"):
                data.append(line[5:].lstrip(" "))
            elif not line and data:
                yield json.loads("\n".join(data))
                data = []
    finally:
        resp.close()
