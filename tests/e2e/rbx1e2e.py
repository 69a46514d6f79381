"""rbx1e2e.py - end-to-end test kit: start rbx1-simfw / rbx1-avrsim and rbx1d, talk to the control socket (through
the rbx1 client library, host/python), read the firmware's move log, and compute the arm's forward kinematics
independently of the C++ code."""
import json
import math
import os
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BIN = ROOT / "build" / "bin"
DATA = ROOT / "data"
# The bundled demo data (scene+calibration engineer's); RBX1_E2E_DEMO points the tests at another such folder.
DEMO = Path(os.environ.get("RBX1_E2E_DEMO", DATA / "demo"))
sys.path.insert(0, str(ROOT / "protocol" / "python"))
sys.path.insert(0, str(ROOT / "host" / "python"))
import rbx1  # noqa: E402  the client library users script with: the tests speak to rbx1d through it


def need(path):
    """A missing build output is a broken build, not a reason to skip: fail with the path."""
    if not Path(path).exists():
        raise AssertionError(f"{path} is missing: build it first (make, or cmake --build build/cmake)")
    return str(path)


# ---- config files ---------------------------------------------------------------------------------------------

def load_default_config():
    with open(DATA / "rbx1.toml", "rb") as f:
        return tomllib.load(f)


def _value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} as TOML")


def dump_toml(d, prefix=""):
    """Enough TOML for our config: scalars, arrays and nested tables."""
    out = []
    scalars = {k: v for k, v in d.items() if not isinstance(v, dict)}
    tables = {k: v for k, v in d.items() if isinstance(v, dict)}
    if prefix and (scalars or not tables):
        out.append(f"[{prefix}]")
    for k, v in scalars.items():
        out.append(f"{k} = {_value(v)}")
    for k, v in tables.items():
        out.append(dump_toml(v, f"{prefix}.{k}" if prefix else k))
    return "\n".join(out) + "\n"


def write_config(tmp, cfg):
    path = Path(tmp) / "rbx1.toml"
    path.write_text(dump_toml(cfg))
    return path


def absolutize(cfg):
    """data/rbx1.toml's relative paths are relative to data/; a copy elsewhere needs them absolute. The demo
    files come from DEMO."""
    def resolve(p):
        if p.startswith("demo/"):
            return str((DEMO / p[len("demo/"):]).resolve())
        return p if p.startswith("/") else str((DATA / p).resolve())
    cam = cfg.setdefault("camera", {})
    if cam.get("device"):
        cam["device"] = resolve(cam["device"])
    vis = cfg.setdefault("vision", {})
    for key in ("background", "library", "calibration"):
        if vis.get(key):
            vis[key] = resolve(vis[key])
    return cfg


def scene_truth():
    """The demo scene's exact truth (the scene generator's JSON)."""
    with open(DEMO / "scene.truth.json") as f:
        return json.load(f)


def truth_label(obj):
    return obj.get("label") or obj["class"]


def scene_labels():
    """Labels of the demo scene's objects, in the truth's order."""
    return [truth_label(o) for o in scene_truth()["objects"]]


# ---- simulators ------------------------------------------------------------------------------------------------

class Simfw:
    """build/bin/rbx1-simfw behind its pty, with a control FIFO and a move log."""

    def __init__(self, tmp, *args, exe="rbx1-simfw", log_moves=True):
        tmp = Path(tmp)
        self.fifo = tmp / f"{exe}.ctl"
        self.log = tmp / f"{exe}.moves.jsonl"
        cmd = [need(BIN / exe), "--control", str(self.fifo)]
        if log_moves:
            cmd += ["--log-moves", str(self.log)]
        cmd += [str(a) for a in args]
        self.stderr = open(tmp / f"{exe}.stderr", "w")
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=self.stderr, text=True)
        self.port = self.proc.stdout.readline().strip()
        if not self.port:
            self.stop()
            raise AssertionError(f"{exe} printed no pty path (exit {self.proc.returncode})")

    def control(self, command):
        fd = os.open(self.fifo, os.O_WRONLY | os.O_NONBLOCK)
        try:
            os.write(fd, (command + "\n").encode())
        finally:
            os.close(fd)

    def moves(self):
        if not self.log.exists():
            return []
        return [json.loads(l) for l in self.log.read_text().splitlines() if l.strip()]

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.stderr.close()
        return self.proc.returncode


class Daemon:
    """build/bin/rbx1d on a config written to tmp, its control socket in tmp."""

    def __init__(self, tmp, cfg, port, wait_ready=True, extra_args=()):
        tmp = Path(tmp)
        self.socket = str(tmp / "rbx1d.sock")
        cfg = json.loads(json.dumps(cfg))  # deep copy
        cfg.setdefault("daemon", {})["socket"] = self.socket
        # The web console on a free port (tests run side by side; the bundled file's 127.0.0.1:8080 may be taken);
        # console_url() reads it from the log.
        console = cfg.setdefault("console", {})
        if console.get("bind", "127.0.0.1:8080") == "127.0.0.1:8080":
            console["bind"] = "127.0.0.1:0"
        # Taught data stays in the test's folder, never in the machine's /var/lib/rbx1.
        cfg["daemon"].setdefault("state_dir", str(tmp / "state"))
        self.config = write_config(tmp, cfg)
        self.log_path = tmp / "rbx1d.log"
        self.log = open(self.log_path, "w")
        self.proc = subprocess.Popen([need(BIN / "rbx1d"), "--config", str(self.config), "--port", str(port),
                                      *extra_args], stdout=self.log, stderr=subprocess.STDOUT)
        try:
            # The socket comes before anything slow (server.open() precedes the link), but a start on a machine
            # at load 18 once took over 10 s to get there: a generous deadline, the condition decides.
            deadline = time.monotonic() + 30
            while not os.path.exists(self.socket):
                if self.proc.poll() is not None:
                    raise AssertionError(f"rbx1d exited {self.proc.returncode}:\n{self.log_path.read_text()}")
                if time.monotonic() > deadline:
                    raise AssertionError("rbx1d did not create its socket")
                time.sleep(0.02)
            if wait_ready:
                self.wait_ready()
        except BaseException:
            # Never leave it running: an orphaned daemon whose simulator goes away reopens the pty's name every
            # 50 ms, and a later test's fresh pty may get that name (CI failures: "in use by another program",
            # bytes stolen from the test's own link).
            self.stop()
            raise

    def wait_ready(self, timeout=15):
        deadline = time.monotonic() + timeout
        while True:
            if self.proc.poll() is not None:
                raise AssertionError(f"rbx1d exited {self.proc.returncode}:\n{self.log_path.read_text()[-3000:]}")
            _, final = self.request({"cmd": "status"})
            if final.get("result", {}).get("ready"):
                return final["result"]
            if time.monotonic() > deadline:
                raise AssertionError(f"rbx1d not ready: {final}\n{self.log_path.read_text()[-3000:]}")
            time.sleep(0.1)

    def request(self, req, timeout=120, on_event=None):
        return request(self.socket, req, timeout, on_event)

    def console_url(self, timeout=10):
        """The web console's address, from the daemon's "console: listening on URL" log line."""
        deadline = time.monotonic() + timeout
        while True:
            for line in self.log_path.read_text().splitlines():
                if "console: listening on " in line:
                    return line.split("console: listening on ", 1)[1].split()[0]
            if time.monotonic() > deadline:
                raise AssertionError(f"rbx1d logged no console address:\n{self.log_path.read_text()[-3000:]}")
            time.sleep(0.05)

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.log.close()
        return self.proc.returncode


def request(sock_path, req, timeout=120, on_event=None):
    """Sends one request (dict or raw line), returns (events, final line); timeout: the longest wait for a line."""
    job = rbx1.Arm(socket=sock_path).send(req, timeout=timeout, on_event=on_event)
    try:
        final = job.wait()
    except rbx1.Disconnected as e:
        if "closed the connection" in e.message:
            raise AssertionError(f"connection closed before the final line; events: {job.events}") from e
        raise  # could not connect: an OSError (ConnectionError), as before
    return job.events, final


# ---- kinematics (independent of host/arm: the chain of host/arm/kinematics.hpp, written out again) -----------


def status(d, timeout=120):
    """The daemon's status result."""
    return d.request({"cmd": "status"}, timeout)[1]["result"]


def position(d):
    """The simulated arm's step position, from the daemon's status."""
    return status(d)["firmware"]["position"]


def ok(d, req):
    """(events, result) of a request that must succeed."""
    events, final = d.request(req)
    assert "result" in final, (req, final)
    return events, final["result"]


def err(d, req):
    """The error of a request that must fail."""
    _, final = d.request(req)
    assert "error" in final, (req, final)
    return final["error"]


def joint_angles(arm, steps):
    out = []
    for i, s in enumerate(steps):
        j = arm["joints"][f"j{i + 1}"]
        per_rev = j["motor_steps"] * j["microsteps"] * j["reduction"]
        out.append(s * 360.0 / per_rev / j["direction"] + j.get("zero_deg", 0.0))
    return out


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return [[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]


def _ry(a):
    c, s = math.cos(a), math.sin(a)
    return [[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]]


def _tz(d):
    return [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, d], [0, 0, 0, 1]]


def _mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def fk(arm, deg):
    """Tool frame: Rz(q1) Tz(base) Ry(q2) Tz(upper) Ry(q3) Tz(fore) Rz(q4) Ry(q5) Tz(tool) Rz(q6)."""
    L = arm["links"]
    q = [math.radians(d) for d in deg]
    T = _rz(q[0])
    for m in (_tz(L["base_height_mm"]), _ry(q[1]), _tz(L["upper_arm_mm"]), _ry(q[2]), _tz(L["forearm_mm"]),
              _rz(q[3]), _ry(q[4]), _tz(L["tool_mm"]), _rz(q[5])):
        T = _mul(T, m)
    return T


def tool_pose(arm, steps):
    """(x, y, z) mm of the tool point, the closing line's yaw folded into (-90, 90], and the tilt from down."""
    T = fk(arm, joint_angles(arm, steps))
    x, y, z = T[0][3], T[1][3], T[2][3]
    yaw = math.degrees(math.atan2(T[1][0], T[0][0]))
    yaw = fold_axis(yaw)
    tilt = math.degrees(math.acos(max(-1.0, min(1.0, -T[2][2]))))
    return (x, y, z), yaw, tilt


def fold_axis(deg):
    while deg <= -90:
        deg += 180
    while deg > 90:
        deg -= 180
    return deg


def axis_diff(a, b):
    return abs(fold_axis(a - b))


def vision_to_base(arm, p_cm, angle_deg):
    """The [arm.camera] mount: base = origin + R(rot) * F * 10 * p_cm; directions map through R * F."""
    cam = arm["camera"]
    rot = math.radians(cam["rotation_deg"])
    fy = -1.0 if cam["flip_y"] else 1.0
    px, py = 10 * p_cm[0], fy * 10 * p_cm[1]
    x = cam["origin_mm"][0] + math.cos(rot) * px - math.sin(rot) * py
    y = cam["origin_mm"][1] + math.sin(rot) * px + math.cos(rot) * py
    a = math.radians(angle_deg)
    dx, dy = math.cos(a), fy * math.sin(a)
    yaw = math.degrees(math.atan2(math.sin(rot) * dx + math.cos(rot) * dy, math.cos(rot) * dx - math.sin(rot) * dy))
    return (x, y), fold_axis(yaw)


# ---- a fast simulated arm -------------------------------------------------------------------------------------

FAST_DEG_S = 90.0  # joint speed of the test arm (the bundled default is 20 deg/s)
FAST_MAX_SPEED, FAST_ACCEL = 20000, 200000  # the test firmware's MAX_SPEED and ACCEL (the defaults: 4000, 8000)


def fast_arm(cfg):
    """The test arm in the daemon's config: FAST_DEG_S, and the firmware limits configure_fast_firmware sets (the
    host times straight lines against them)."""
    arm = cfg.setdefault("arm", {})
    arm.setdefault("speeds", {})["joint_speed_deg_s"] = FAST_DEG_S
    for j in range(1, 7):
        joint = arm.setdefault("joints", {}).setdefault(f"j{j}", {})
        joint.update(max_speed_steps_s=FAST_MAX_SPEED, accel_steps_s2=FAST_ACCEL)
    return cfg


def configure_fast_firmware(port):
    """Raises the firmware's per-joint MAX_SPEED and ACCEL (EEPROM config, protocol CONFIG_SET) so that the test
    arm can move at FAST_DEG_S; the daemon then plans at that speed."""
    from rbx1proto.link import Link
    from rbx1proto.messages import JOINTS, Key, MsgType
    with Link(port) as link:
        link.hello()
        for j in range(JOINTS):
            for key, value in ((Key.MAX_SPEED, FAST_MAX_SPEED), (Key.ACCEL, FAST_ACCEL)):
                r = link.request(MsgType.CONFIG_SET, joint=j, key=key, value=value)
                assert r["status"] == 0, (j, key, r)


# ---- checking what the firmware executed against what was planned -------------------------------------------

def planned_waypoints(events):
    """The waypoints of the pick's "planned" event, in order."""
    planned = [e for e in events if e["event"] == "planned"]
    assert len(planned) == 1, [e["event"] for e in events]
    return planned[0]["waypoints"]


def entry_matches(entry, wp):
    if wp["kind"] == "gripper":
        return entry["kind"] == "gripper" and entry.get("pulse_us") == wp["pulse_us"]
    return entry["kind"] == "move" and list(entry["target"]) == list(wp["target"])


def assert_log_is_plan(log, waypoints):
    """The executed entries are exactly the planned ones, in order: none lost, none repeated."""
    got = [(e["kind"], e["target"] if e["kind"] == "move" else e.get("pulse_us")) for e in log]
    want = [(w["kind"], w["target"] if w["kind"] == "move" else w["pulse_us"]) for w in waypoints]
    assert got == want, f"executed {len(got)} entries, planned {len(want)}:\n{got}\n{want}"
    for e in log:
        if e["kind"] == "move":
            assert list(e["end"]) == list(e["target"]), e


def events_named(events, name):
    return [e for e in events if e["event"] == name]


def configure_fast_firmware_retrying(port, tries=5):
    """configure_fast_firmware over a link with injected faults (the Python link retransmits; HELLO may still
    fail now and then)."""
    last = None
    for _ in range(tries):
        try:
            return configure_fast_firmware(port)
        except Exception as e:  # LinkError, a corrupted response
            last = e
    raise AssertionError(f"could not configure the firmware: {last}")


def home_steps(arm):
    """The home pose in steps (joint config rounding: halves away from zero)."""
    out = []
    for i, deg in enumerate(arm["poses"]["home"]):
        j = arm["joints"][f"j{i + 1}"]
        v = j["direction"] * (deg - j.get("zero_deg", 0.0)) * j["motor_steps"] * j["microsteps"] * j["reduction"] / 360
        out.append(int(math.floor(abs(v) + 0.5)) * (1 if v >= 0 else -1))
    return out
