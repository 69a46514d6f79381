"""mqttkit.py - a real mosquitto for the tests (free loopback port, password file, ACL in the shape of
tools/cell/rbx1-cell.acl) and a paho-mqtt watcher that records every message it sees."""
import json
import os
import pwd
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path

import paho.mqtt.client as mqtt

ROOT = Path(__file__).resolve().parents[2]
CELL_TOOL = ROOT / "tools" / "cell" / "cell"


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class Broker:
    """mosquitto with one user per arm (its own prefix only) and a controller (reads all, writes commands)."""

    def __init__(self, tmp, arms):
        self.dir = Path(tmp) / "broker"
        self.dir.mkdir(parents=True, exist_ok=True)
        self.port = free_port()
        passwd = self.dir / "passwd"
        self.passwords = {name: f"{name}-secret" for name in [*arms, "controller"]}
        for i, (user, pw) in enumerate(self.passwords.items()):
            subprocess.run(["mosquitto_passwd", *(["-c"] if i == 0 else []), "-b", str(passwd), user, pw], check=True,
                           capture_output=True)
            (self.dir / f"{user}.pw").write_text(pw + "\n")
        # As tools/cell/rbx1-cell.acl: the controller here is also Home Assistant (discovery, the recipe select).
        (self.dir / "acl").write_text("pattern readwrite rbx1/%u/#\npattern readwrite homeassistant/+/%u/#\n"
                                      "user controller\ntopic read rbx1/#\ntopic write rbx1/+/cmd\n"
                                      "topic read homeassistant/#\ntopic write rbx1/+/recipe/set\n"
                                      "topic write rbx1/+/recipe/sort\n")
        (self.dir / "mosquitto.conf").write_text(
            f"user {pwd.getpwuid(os.geteuid()).pw_name}\nallow_anonymous false\npassword_file {passwd}\n"
            f"acl_file {self.dir / 'acl'}\npersistence false\nlog_dest file {self.dir / 'mosquitto.log'}\n"
            f"listener {self.port} 127.0.0.1\n")
        self.proc = None
        self.start()

    def password_file(self, user):
        return str(self.dir / f"{user}.pw")

    def start(self):
        self.proc = subprocess.Popen(["mosquitto", "-c", str(self.dir / "mosquitto.conf")],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.2).close()
                return
            except OSError:
                time.sleep(0.05)
        raise AssertionError("mosquitto did not start listening")

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            self.proc.wait(timeout=5)


def mqtt_section(broker, arm, **extra):
    """The [mqtt] table of an arm on this broker."""
    return {"enabled": True, "host": "127.0.0.1", "port": broker.port, "username": arm,
            "password_file": broker.password_file(arm), "keepalive_s": 5, "state_rate_hz": 10.0, **extra}


class Watcher:
    """A controller client subscribed to rbx1/# (and any other topics given): every message kept, in order."""

    def __init__(self, broker, user="controller", topics=("rbx1/#",)):
        self.messages = []
        self.lock = threading.RLock()  # wait()'s predicates call last()
        self.c = mqtt.Client(client_id=f"watch-{free_port()}", protocol=mqtt.MQTTv5)
        self.c.username_pw_set(user, broker.passwords[user])
        self.c.on_message = self._on_message
        self.c.on_connect = lambda c, u, f, rc, p=None: c.subscribe([(t, 1) for t in topics])
        self.c.reconnect_delay_set(0.2, 1)
        self.c.connect("127.0.0.1", broker.port, keepalive=10)
        self.c.loop_start()

    def _on_message(self, client, userdata, msg):
        with self.lock:
            self.messages.append((msg.topic, msg.payload.decode(errors="replace"), msg.retain))

    def wait(self, pred, timeout=15, what="a message"):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                for m in self.messages:
                    if pred(*m):
                        return m
            time.sleep(0.05)
        with self.lock:
            tail = self.messages[-10:]
        raise AssertionError(f"no {what} within {timeout} s; last: {tail}")

    def last(self, topic):
        with self.lock:
            for t, p, _ in reversed(self.messages):
                if t == topic:
                    return p
        return None

    def wait_status(self, arm, value, timeout=15):
        return self.wait(lambda t, p, r: t == f"rbx1/{arm}/status" and p == value and self.last(t) == value, timeout,
                         f"rbx1/{arm}/status {value}")

    def topics(self):
        with self.lock:
            return [t for t, _, _ in self.messages]

    def close(self):
        self.c.disconnect()
        self.c.loop_stop()


def cell(broker, *args, timeout=180):
    """tools/cell/cell as the controller: (exit code, stdout, stderr)."""
    p = subprocess.run(["/usr/bin/python3", str(CELL_TOOL), "--host", "127.0.0.1", "--port", str(broker.port),
                        "--username", "controller", "--password-file", broker.password_file("controller"), *args],
                       capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def reply_of(stdout):
    return json.loads(stdout.strip().splitlines()[-1])
