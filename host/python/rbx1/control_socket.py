"""control_socket.py - rbx1d's Unix control socket: one connection per request, its JSON reply lines as they come."""
import json
import socket

from .errors import Disconnected, NoReply


def encode(request):
    """A request (a dict, or a raw line as str or bytes) as the bytes to write, newline-terminated."""
    if isinstance(request, dict):
        data = json.dumps(request).encode()
    elif isinstance(request, str):
        data = request.encode()
    else:
        data = bytes(request)
    return data if data.endswith(b"\n") else data + b"\n"


def connect(path, timeout):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.settimeout(timeout)
    try:
        s.connect(path)
    except OSError as e:
        s.close()
        raise Disconnected(f"cannot connect to rbx1d at {path}: {e.strerror or e}") from e
    return s


def lines(path, request, timeout):
    """Sends request on a new connection and yields each reply line (a dict) until the connection closes; timeout:
    the longest wait in seconds for the next bytes (None: no limit). Closing the generator closes the connection
    (a jog's client going away stops the jog)."""
    s = connect(path, timeout)
    try:
        try:
            s.sendall(encode(request))
        except OSError as e:
            raise Disconnected(f"rbx1d at {path} closed the connection: {e.strerror or e}") from e
        buf = b""
        while True:
            try:
                chunk = s.recv(65536)
            except socket.timeout as e:
                raise NoReply(f"no reply line from rbx1d at {path} within {timeout} s") from e
            except OSError as e:
                raise Disconnected(f"rbx1d at {path} closed the connection: {e.strerror or e}") from e
            if not chunk:
                raise Disconnected(f"rbx1d at {path} closed the connection before the final line")
            buf += chunk
            while b"\n" in buf:
                raw, buf = buf.split(b"\n", 1)
                if raw.strip():
                    yield json.loads(raw)
    finally:
        s.close()
