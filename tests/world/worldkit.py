"""worldkit.py - the closed-loop kit: make a world (tools/world/make-world), run rbx1-world (rbx1-simfw inside),
configure rbx1d for it (lens calibration and nominal camera mapping from the world, a fast arm), calibrate the
workspace as an operator would (the marker sheet on the table, the tool point jogged onto each marker by eye, fit,
save), pick, and read the world's truth. Used by tests/world and tools/bench/world."""
import itertools
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
TOUCH_Z_MM = 0.5        # an operator lowers the tool point until it just touches the marker
TOUCH_TOL_MM = 0.15     # and judges the touch by eye to this
TOUCH_FLOOR_MM = 0.2    # or, when the daemon will not go lower, this far above the daemon's idea of the table


def make_world(path, seed, objects="5-10", errors=(1.0, 5.0, 3.0), k1=-0.08, drift=0.05, classes=None,
               class_heights=False):
    cmd = [sys.executable, str(MAKE_WORLD), "--seed", str(seed), "--objects", str(objects),
           "--errors", ",".join(str(e) for e in errors), "--k1", str(k1), "--drift", str(drift), "--out", str(path)]
    subprocess.run(cmd + (["--classes", classes] if classes else []) + (["--class-heights"] if class_heights else []),
                   check=True)
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
            self.stop()
            raise AssertionError(f"rbx1-world printed {self.camera!r}, {self.port!r} (exit {self.proc.poll()})")
        self.time_scale = time_scale

    def state(self):
        return json.loads(self.ask("state"))

    def markers(self, on):
        """The operator lays the marker sheet on the table (the objects set aside) or takes it away."""
        self._ok("markers on" if on else "markers off")

    def clear_table(self, cleared):
        """The operator takes the objects off the table (the empty table for `rbx1 background`) or puts them back."""
        self._ok("table clear" if cleared else "table objects")

    def light(self, gain, offset):
        """The light from now on: every frame * gain + offset (the light sweep's levels)."""
        self._ok(f"light {gain} {offset}")

    def _ok(self, request):
        reply = self.ask(request)
        if reply.strip() != "ok":
            raise AssertionError(f"rbx1-world: {request}: {reply.strip()}")

    def ask(self, request):
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.settimeout(10)
        s.connect(self.camera[len("unix:"):])
        s.sendall(request.encode() + b"\n")
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(1 << 20)
            if not chunk:
                break
            buf += chunk
        s.close()
        return buf.decode()

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
    cfg["console"] = {"bind": "127.0.0.1:0"}  # cells run side by side
    d = cfg.setdefault("daemon", {})
    d.update({"status_poll_ms": STATUS_POLL_MS, "verify_pick": True, "pick_retries": 1, "log_level": "info",
              "job_timeout_s": 120.0})
    arm = e2e.fast_arm(cfg)["arm"]
    arm["camera"] = arm_camera
    cfg["operator"] = {"jog_max_mm": 500.0, "jog_max_deg": 180.0}
    arm["places"] = {p["name"]: {"x_mm": p["x_mm"], "y_mm": p["y_mm"], "z_mm": p.get("z_mm", 0.0),
                                 "yaw_deg": p.get("yaw_deg", 0.0)} for p in scene["places"]}
    return cfg


def true_view(scene_path):
    """The table corners (base frame, mm) the world's true camera sees at the scan pose (`rbx1-world --view`)."""
    out = subprocess.run([e2e.need(e2e.BIN / "rbx1-world"), "--scene", str(scene_path), "--view"],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)["true_view_mm"]


def place_in_view(scene_path, index, along=0.0, yaw_deg=None):
    """Object `index` of the scene moved to the true view's centre plus `along` times the half of its longer side
    (0: under the camera; 0.7: well off the optical axis), turned to yaw_deg when given."""
    c = true_view(scene_path)
    cx, cy = sum(p[0] for p in c) / 4, sum(p[1] for p in c) / 4
    sides = [(c[1][0] - c[0][0], c[1][1] - c[0][1]), (c[2][0] - c[1][0], c[2][1] - c[1][1])]
    lx, ly = max(sides, key=lambda v: v[0] ** 2 + v[1] ** 2)
    doc = json.loads(Path(scene_path).read_text())
    obj = doc["objects"][index]
    obj["x_mm"], obj["y_mm"] = round(cx + along * lx / 2, 3), round(cy + along * ly / 2, 3)
    if yaw_deg is not None:
        obj["yaw_deg"] = yaw_deg
    Path(scene_path).write_text(json.dumps(doc, indent=1))


class Cell:
    """A world and rbx1d on it, ready to pick."""

    def __init__(self, tmp, scene_path, annotate=None, time_scale=TIME_SCALE, library=None):
        with open(scene_path) as f:
            self.scene = json.load(f)
        self.world = World(tmp, scene_path, time_scale)
        try:
            configure_firmware(self.world.port)
            cfg = daemon_config(tmp, scene_path, self.scene, self.world.camera)
            if annotate:
                cfg["daemon"]["annotate"] = str(annotate)
            if library:  # a library taught before (Cell.teach_all in another world), as the configured one
                cfg["vision"]["library"] = str(library)
            self.daemon = e2e.Daemon(tmp, cfg, self.world.port)  # stops itself when it does not get ready
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

    def ok(self, req):
        events, final = self.daemon.request(req)
        if "result" not in final:
            raise AssertionError(f"{req}: {final}")
        return final["result"]

    def touch(self, x, y, z=TOUCH_Z_MM, tol_mm=TOUCH_TOL_MM):
        """Jogs the tool point onto (x, y, z) mm as an operator does, judging by eye (the world's true tool point,
        not the daemon's belief): up to 30 mm above the table, across, down, then small corrections. Where the
        daemon believes the tool lower than it is (link errors) it refuses to go below its table: the operator
        stops TOUCH_FLOOR_MM above the daemon's table then. Returns the number of jogs."""
        jogs = 0

        def tool():
            return self.world.state()["arm"]["tool_mm"]

        def jog(d):
            r = self.ok({"cmd": "jog", "mm": d})
            return r["tool"]["z_mm"]

        t = tool()
        if t[2] < 30.0:
            jog([0.0, 0.0, 30.0 - t[2]])
            jogs += 1
        t = tool()
        believed_z = jog([x - t[0], y - t[1], 30.0 - t[2]])
        jogs += 1
        for _ in range(6):
            t = tool()
            dz = max(z - t[2], TOUCH_FLOOR_MM - believed_z)
            d = [x - t[0], y - t[1], dz]
            if max(abs(v) for v in d) <= tol_mm:
                return jogs
            believed_z = jog(d)
            jogs += 1
        raise AssertionError(f"the tool point did not reach ({x}, {y}, {z}) mm by eye: at {tool()}")

    def calibrate_workspace(self):
        """issue 11's workspace calibration in the world: the sheet on the table, `start` at the scan pose, each
        marker the camera found touched and recorded, `fit`, `save`, the sheet taken away. Returns the fit's
        reply (rms_mm, max_loo_mm, markers) with the markers seen and the jogs made."""
        self.world.markers(True)
        truth = {m["id"]: m for m in self.world.state()["markers"]}
        start = self.ok({"cmd": "calibrate_workspace", "action": "start"})
        seen = [m["id"] for m in start["markers"]]
        jogs = 0
        for i in seen:
            jogs += self.touch(truth[i]["x_mm"], truth[i]["y_mm"])
            self.ok({"cmd": "calibrate_workspace", "action": "record", "marker": i})
        self.ok({"cmd": "jog", "mm": [0.0, 0.0, 30.0]})  # off the table before the scan pose
        fit = self.ok({"cmd": "calibrate_workspace", "action": "fit"})
        if fit.get("accepted"):
            fit["saved"] = self.ok({"cmd": "calibrate_workspace", "action": "save"}).get("saved")
        else:
            self.ok({"cmd": "calibrate_workspace", "action": "cancel"})
        self.world.markers(False)
        fit["seen"] = seen
        fit["jogs"] = jogs
        return fit


def table_distance_mm(a, b):
    """Distance on the table between two things with x_mm, y_mm (an object of the world, a detection's place)."""
    return ((a["x_mm"] - b["x_mm"]) ** 2 + (a["y_mm"] - b["y_mm"]) ** 2) ** 0.5


def least_total_pairs(n, m, cost):
    """The pairs (i, k), i < n, k < m, covering the shorter side, each index at most once, of least total cost."""
    if m < n:
        return [(i, k) for k, i in least_total_pairs(m, n, lambda k, i: cost(i, k))]
    return min((list(zip(range(n), ks)) for ks in itertools.permutations(range(m), n)),
               key=lambda ps: sum(cost(i, k) for i, k in ps))


def teach_all(cell, tol_mm=15.0):
    """Teaches every object of the world once from the camera, as an operator does: `scan`, the live view's
    objects on the table (`scene`: each detection where the map in force puts it), each object of the world
    pointed at (detections matched to the objects' true places, the assignment of least total distance, so a
    common offset of the camera's view does not mix them up; a match farther than tol_mm is no match),
    `teach --from-camera INDEX --name CLASS`. Returns the state library's path (None when nothing was taught) and
    one record per object: class, index, distance (mm), the daemon's reply (self-match figures) or error (an
    object the scan did not find: error "not_found" with the scan's report)."""
    scan = cell.ok({"cmd": "scan"})
    seen = cell.ok({"cmd": "scene"})["objects"]
    objs = [o for o in cell.world.state()["objects"] if o["place"] is None and not o["held"]]

    dist = table_distance_mm
    pairs = least_total_pairs(len(objs), len(seen), lambda i, k: dist(objs[i], seen[k]))
    match = {i: k for i, k in pairs if dist(objs[i], seen[k]) <= tol_mm}
    records, library = [], None
    for i, o in enumerate(objs):
        if i not in match:
            records.append({"class": o["class"], "index": None, "distance_mm": None, "result": None,
                            "error": {"code": "not_found", "message": scan["report"]}})
            continue
        d = seen[match[i]]
        events, final = cell.daemon.request({"cmd": "teach", "index": d["index"], "name": o["class"]})
        records.append({"class": o["class"], "index": d["index"], "distance_mm": round(dist(o, d), 2),
                        "result": final.get("result"), "error": final.get("error")})
        library = (final.get("result") or {}).get("library", library)
    return library, records


def capture_background(cell, frames=8):
    """`rbx1 background` as an operator does it: the objects taken off the table, the empty table captured at the
    scan pose (in force for every later scan), the objects put back."""
    cell.world.clear_table(True)
    try:
        return cell.ok({"cmd": "background", "frames": frames})
    finally:
        cell.world.clear_table(False)


def found_by_scan(cell, tol_mm=6.0):
    """A scan judged by the world: each object on the table found when a detection named with its class lies
    within tol_mm of it (where the map in force puts it; a tall object's top is seen up to about 3 mm off its
    footprint's centre at the view's edge). Returns (found, on the table, detections left over)."""
    cell.ok({"cmd": "scan"})
    seen = cell.ok({"cmd": "scene"})["objects"]
    objs = [o for o in cell.world.state()["objects"] if o["place"] is None and not o["held"]]
    used, found = set(), 0
    for o in objs:
        near = [k for k, d in enumerate(seen)
                if k not in used and d["label"] == o["class"] and table_distance_mm(o, d) <= tol_mm]
        if near:
            used.add(near[0])
            found += 1
    return found, len(objs), len(seen) - len(used)


def light_level(cell, gain, offset):
    """One level of the light sweep in a cell whose background was captured at nominal light: the light set to
    frame * gain + offset, a scan judged by the world (found_by_scan), then every object picked by name.
    Returns dict(found, expected, phantoms, picks, placed: in the place asked for, by the world's state,
    wrong: placements of another class, errors: the daemon's error codes)."""
    cell.world.light(gain, offset)
    found, expected, phantoms = found_by_scan(cell)
    records, wrong = [], 0
    for i, obj in enumerate(cell.scene["objects"]):
        place = "tray" if i % 2 == 0 else "bin"
        before = len(cell.world.state()["events"])
        events, final, _ = cell.pick(obj["class"], place)
        new = cell.world.state()["events"][before:]
        wrong += sum(1 for e in new if e["event"] == "placement" and e["class"] != obj["class"])
        records.append({"label": obj["class"], "place": place, "ok": "result" in final, "final": final})
    state = cell.world.state()
    return {"gain": gain, "offset": offset, "found": found, "expected": expected, "phantoms": phantoms,
            "picks": len(records), "placed": placed_correctly(state, records), "wrong": wrong,
            "errors": sorted({r["final"]["error"]["code"] for r in records if not r["ok"]})}


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
