"""worldkit.py - the closed-loop kit: make a world (tools/world/make-world), run rbx1-world (rbx1-simfw inside),
configure rbx1d for it (lens calibration and nominal camera mapping from the world, a fast arm), pick, and read
the world's truth. Used by tests/world and tools/bench/world."""
import json
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "e2e"))
import rbx1e2e as e2e  # noqa: E402

MAKE_WORLD = ROOT / "tools" / "world" / "make-world"
TIME_SCALE = 4.0        # rbx1-simfw's clock runs this much faster than the wall clock
HEARTBEAT_MS = 8000     # the firmware's heartbeat timeout (simulated ms): a loaded test machine may stall the host
STATUS_POLL_MS = 20     # the daemon's polling while moving (80 simulated ms)


def make_world(path, seed, objects="5-10", errors=(1.0, 5.0, 3.0), k1=-0.08, drift=0.05, classes=None):
    cmd = [sys.executable, str(MAKE_WORLD), "--seed", str(seed), "--objects", str(objects),
           "--errors", ",".join(str(e) for e in errors), "--k1", str(k1), "--drift", str(drift), "--out", str(path)]
    subprocess.run(cmd + (["--classes", classes] if classes else []), check=True)
    with open(path) as f:
        return json.load(f)


class World:
    """build/bin/rbx1-world on a scene: the camera device and the serial port it prints, its state on request."""

    def __init__(self, tmp, scene_path, time_scale=TIME_SCALE):
        tmp = Path(tmp)
        self.state_path = tmp / "world.state.json"
        self.events_path = tmp / "world.events.jsonl"
        self.stderr = open(tmp / "rbx1-world.stderr", "w")
        self.proc = subprocess.Popen([e2e.need(e2e.BIN / "rbx1-world"), "--scene", str(scene_path),
                                      "--time-scale", str(time_scale), "--events", str(self.events_path),
                                      "--state", str(self.state_path)],
                                     stdout=subprocess.PIPE, stderr=self.stderr, text=True)
        self.camera = self.proc.stdout.readline().strip()
        self.port = self.proc.stdout.readline().strip()
        if not self.camera.startswith("unix:") or not self.port:
            raise AssertionError(f"rbx1-world printed {self.camera!r}, {self.port!r} (exit {self.proc.poll()})")
        self.time_scale = time_scale

    def state(self):
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.settimeout(10)
        s.connect(self.camera[len("unix:"):])
        s.sendall(b"state\n")
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(1 << 20)
            if not chunk:
                break
            buf += chunk
        s.close()
        return json.loads(buf)

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.stderr.close()
        return self.proc.returncode


def configure_firmware(port):
    """The fast test arm of tests/e2e (MAX_SPEED, ACCEL) and a heartbeat timeout that survives host stalls."""
    from rbx1proto.link import Link
    from rbx1proto.messages import Key, MsgType
    e2e.configure_fast_firmware(port)
    with Link(port) as link:
        link.hello()
        r = link.request(MsgType.CONFIG_SET, joint=0xFF, key=Key.HEARTBEAT_MS, value=HEARTBEAT_MS)
        assert r["status"] == 0, r


def daemon_config(tmp, scene_path, scene, camera):
    """data/rbx1.toml for this world: the frames from the world's socket, the lens calibration and the nominal
    [arm.camera] mapping computed by rbx1-world from the nominal arm and mount (what the daemon believes), the
    bundled library, the world's places, a fast arm and the pick check."""
    tmp = Path(tmp)
    calib = tmp / "world.calibration.json"
    out = subprocess.run([e2e.need(e2e.BIN / "rbx1-world"), "--scene", str(scene_path), "--write-calibration",
                          str(calib)], check=True, capture_output=True, text=True).stdout
    arm_camera = json.loads(out)["arm_camera"]
    cfg = e2e.absolutize(e2e.load_default_config())
    cfg["camera"]["device"] = camera
    vis = cfg["vision"]
    vis.pop("px_per_cm", None)
    vis["calibration"] = str(calib)
    vis["background"] = ""
    vis["objects"] = "dark"
    cfg["link"]["heartbeat_ms"] = 50
    d = cfg.setdefault("daemon", {})
    d.update({"status_poll_ms": STATUS_POLL_MS, "verify_pick": True, "pick_retries": 1, "log_level": "info",
              "job_timeout_s": 120.0})
    arm = cfg.setdefault("arm", {})
    arm.setdefault("speeds", {})["joint_speed_deg_s"] = e2e.FAST_DEG_S
    arm["camera"] = arm_camera
    arm["places"] = {p["name"]: {"x_mm": p["x_mm"], "y_mm": p["y_mm"], "z_mm": p.get("z_mm", 0.0),
                                 "yaw_deg": p.get("yaw_deg", 0.0)} for p in scene["places"]}
    return cfg


class Cell:
    """A world and rbx1d on it, ready to pick."""

    def __init__(self, tmp, scene_path, annotate=None):
        with open(scene_path) as f:
            self.scene = json.load(f)
        self.world = World(tmp, scene_path)
        try:
            configure_firmware(self.world.port)
            cfg = daemon_config(tmp, scene_path, self.scene, self.world.camera)
            if annotate:
                cfg["daemon"]["annotate"] = str(annotate)
            self.daemon = e2e.Daemon(tmp, cfg, self.world.port)
        except BaseException:
            self.world.stop()
            raise

    def pick(self, label, place):
        t0 = time.monotonic()
        events, final = self.daemon.request({"cmd": "pick", "name": label, "place": place}, timeout=180)
        return events, final, time.monotonic() - t0

    def stop(self):
        self.daemon.stop()
        return self.world.stop()


def pick_all(cell, place_of=lambda i, obj: "tray" if i % 2 == 0 else "bin"):
    """Picks every object of the scene once by its label (a label twice in the scene: picked twice, the daemon
    choosing). Returns one record per pick: label, place, ok, the daemon's final line, the events' names,
    pick_failed events, wall seconds."""
    records = []
    for i, obj in enumerate(cell.scene["objects"]):
        place = place_of(i, obj)
        events, final, secs = cell.pick(obj["class"], place)
        records.append({"label": obj["class"], "place": place, "ok": "result" in final, "final": final,
                        "events": [e.get("event") for e in events],
                        "pick_failed": [e for e in events if e.get("event") == "pick_failed"],
                        "identified": [e for e in events if e.get("event") == "identified"],
                        "seconds": secs})
    return records


def placed_correctly(state, records):
    """Objects the world has where the picks asked for them: per class and place, the fewer of (picks that asked
    for that place, objects of that class resting there). The daemon picks a label's best match, so which of two
    objects of one class went where is its choice."""
    from collections import Counter
    asked = Counter((r["label"], r["place"]) for r in records)
    there = Counter((o["class"], o["place"]) for o in state["objects"] if o["place"] and not o["held"])
    return sum(min(n, there[key]) for key, n in asked.items())
