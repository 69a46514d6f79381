"""test_operator.py - the operator's commands against rbx1-simfw: jog by exact step counts, degrees and tool-point
millimetres; jogs beyond the limits or the per-request bound refused with nothing moved; the dead-man STOP when the
client goes away; the scan pose, a place, the background and a taught object saved in the state directory and still
in force after a restart."""
import json
import math
import subprocess
import time

import rbx1e2e as e2e
from rbx1e2e import err, ok, position
from conftest import fast_config

J1_STEPS_PER_DEG = 200 * 16 * 10.67 / 360


def test_jog_moves_exact_steps_and_refuses_beyond_limits(sim, daemon_factory, tmp_path):
    cfg = fast_config()
    cfg["operator"] = {"jog_max_deg": 180.0, "jog_max_mm": 400.0}
    d = daemon_factory(sim.port, cfg)
    arm = e2e.load_default_config()["arm"]
    start = position(d)
    assert start == e2e.home_steps(arm)
    # Joint steps: exactly that many on that joint, nothing elsewhere.
    _, r = ok(d, {"cmd": "jog", "joint": 2, "steps": 100})
    assert r["moved_steps"] == [0, 100, 0, 0, 0, 0]
    assert position(d) == [start[0], start[1] + 100] + start[2:]
    assert sim.moves()[-1]["end"] == position(d)
    _, r = ok(d, {"cmd": "jog", "joint": 2, "steps": -100})
    assert position(d) == start
    # Degrees: the angle rounded to steps (1.5 deg of J1 = 142.27 steps -> 142).
    _, r = ok(d, {"cmd": "jog", "joint": 1, "deg": 1.5})
    assert r["moved_steps"] == [round(1.5 * J1_STEPS_PER_DEG), 0, 0, 0, 0, 0] == [142, 0, 0, 0, 0, 0]
    ok(d, {"cmd": "jog", "joint": 1, "deg": -1.5})
    assert position(d) == start

    # Beyond the limits, beyond the table, a tool jog with the tool not pointing down: refused, nothing moved.
    moves = len(sim.moves())
    e = err(d, {"cmd": "jog", "joint": 2, "deg": 106})
    assert e["code"] == "out_of_limits" and "J2 (shoulder)" in e["message"] and "max_deg = 105" in e["message"], e
    assert "nothing moved" in e["message"]
    e = err(d, {"cmd": "jog", "joint": 3, "steps": -1000000})
    assert e["code"] in ("out_of_limits", "jog_too_far"), e
    e = err(d, {"cmd": "jog", "mm": [10, 0, 0]})  # at home the tool points up
    assert e["code"] == "bad_pose", e
    assert len(sim.moves()) == moves and position(d) == start

    # The tool point by millimetres, yaw kept, from the scan pose (tool pointing down).
    ok(d, {"cmd": "scan"})
    (x0, y0, z0), yaw0, _ = e2e.tool_pose(arm, position(d))
    _, r = ok(d, {"cmd": "jog", "mm": [10, -5, -20]})
    (x, y, z), yaw, tilt = e2e.tool_pose(arm, position(d))
    assert abs(x - x0 - 10) < 0.1 and abs(y - y0 + 5) < 0.1 and abs(z - z0 + 20) < 0.1, (x - x0, y - y0, z - z0)
    assert e2e.axis_diff(yaw, yaw0) < 0.12 and tilt < 0.05  # within one J6 step (0.1125 deg)
    assert abs(r["tool"]["x_mm"] - x) < 0.01
    moves = len(sim.moves())
    e = err(d, {"cmd": "jog", "mm": [0, 0, -z - 1]})
    assert e["code"] == "out_of_limits" and "below the table" in e["message"], e
    e = err(d, {"cmd": "jog", "mm": [0, 0, 401]})
    assert e["code"] == "jog_too_far", e
    e = err(d, {"cmd": "jog", "mm": [600, 0, 0]})
    assert e["code"] == "jog_too_far", e
    assert len(sim.moves()) == moves
    # Malformed jogs: usage errors.
    for bad in ({"cmd": "jog"}, {"cmd": "jog", "joint": 7, "steps": 1}, {"cmd": "jog", "joint": 1, "steps": 1, "deg": 1},
                {"cmd": "jog", "mm": [1, 2]}, {"cmd": "jog", "mm": [1, 2, 3], "joint": 1}, {"cmd": "jog", "speed": 3}):
        assert err(d, bad)["code"] in ("missing_field", "bad_field", "bad_request"), bad
    assert len(sim.moves()) == moves

    # The CLI: same request, exit codes 0 / 1 / 2.
    env = {"RBX1_SOCKET": d.socket, "PATH": "/usr/bin:/bin"}
    cli = lambda *a: subprocess.run([e2e.need(e2e.BIN / "rbx1"), *a], capture_output=True, text=True, env=env, timeout=60)
    before = position(d)
    r = cli("jog", "--joint", "6", "--steps", "-40")
    assert r.returncode == 0, r.stderr
    assert position(d) == before[:5] + [before[5] - 40]
    r = cli("jog", "--joint", "5", "--deg", "150")
    assert r.returncode == 1 and "out_of_limits" in r.stderr, r.stderr
    r = cli("jog", "--joint", "5")
    assert r.returncode == 2 and "--steps" in r.stderr, r.stderr


def test_jog_stops_when_the_client_goes_away(sim, daemon_factory):
    cfg = fast_config()
    cfg["arm"]["speeds"]["joint_speed_deg_s"] = 5.0  # 10 deg take 2 s: time to hang up mid-move
    d = daemon_factory(sim.port, cfg)
    start = position(d)
    job = e2e.rbx1.Arm(socket=d.socket).start("jog", joint=1, deg=10, timeout=30)
    next(e for e in job if e["event"] == "step")
    time.sleep(0.3)
    job.close()  # the operator's client died mid-jog
    deadline = time.monotonic() + 10
    while True:
        _, st = d.request({"cmd": "status"})
        st = st["result"]
        if st["job"] is None and st["firmware"]["state"] == "IDLE":
            break
        assert time.monotonic() < deadline, st
        time.sleep(0.05)
    moved = st["firmware"]["position"][0] - start[0]
    full = round(10 * J1_STEPS_PER_DEG)
    assert 0 < moved < full * 0.6, (moved, full)  # stopped early, not run to the end
    assert st["ready"], st
    assert "STOP sent" in d.log_path.read_text()


def test_taught_data_is_saved_and_survives_a_restart(sim, daemon_factory, tmp_path):
    cfg = fast_config()
    cfg["operator"] = {"jog_max_mm": 500.0}
    d = daemon_factory(sim.port, cfg)
    arm = e2e.load_default_config()["arm"]
    state = tmp_path / "state"
    # The scan pose: from the configured one, J1 turned by 2 degrees.
    ok(d, {"cmd": "scan"})
    ok(d, {"cmd": "jog", "joint": 1, "deg": 2})
    scan_steps = position(d)
    _, r = ok(d, {"cmd": "pose_save", "name": "scan"})
    assert r["saved"] == str(state / "poses.json")
    saved = json.loads((state / "poses.json").read_text())["scan"]
    assert [round(a, 6) for a in saved] == [round(a, 6) for a in e2e.joint_angles(arm, scan_steps)]
    assert err(d, {"cmd": "pose_save", "name": "home"})["code"] == "bad_field"
    # A place: the tool point lowered onto a surface 20 mm above the table, turned 10 degrees.
    ok(d, {"cmd": "home"})
    ok(d, {"cmd": "scan"})
    ok(d, {"cmd": "jog", "mm": [-100, 150, -340]})
    ok(d, {"cmd": "jog", "joint": 6, "deg": 10})
    (px, py, pz), pyaw, _ = e2e.tool_pose(arm, position(d))
    _, r = ok(d, {"cmd": "place_save", "name": "bin"})
    place = json.loads((state / "places.json").read_text())["bin"]
    assert abs(place["x_mm"] - px) < 0.01 and abs(place["y_mm"] - py) < 0.01 and abs(place["z_mm"] - pz) < 0.01
    assert e2e.axis_diff(place["yaw_deg"], pyaw) < 0.01
    # Teach object 1 of the live scan under a new name: the state library = the configured one plus it.
    _, scan = ok(d, {"cmd": "scan"})
    n_lib = len(json.loads(open(cfg["vision"]["library"]).read())["objects"])
    _, r = ok(d, {"cmd": "teach", "index": 1, "name": "widget"})
    lib = json.loads((state / "library.json").read_text())
    assert r["objects_in_library"] == len(lib["objects"]) == n_lib + 1
    # Object 1 is in the library already: taught anyway, with a warning naming its entry (issue 27).
    known = next(o["label"] for o in scan["detections"]["objects"] if o["index"] == 1)
    assert known and len(r["warnings"]) == 1, r
    assert f'"widget" looks like "{known}" already in the library (match ' in r["warnings"][0], r
    assert err(d, {"cmd": "teach", "index": 99, "name": "x"})["code"] == "no_object"
    d.stop()

    # Restarted on the same state: the taught scan pose, place and library are in force.
    d = daemon_factory(sim.port, cfg)
    ok(d, {"cmd": "home"})
    _, scan = ok(d, {"cmd": "scan"})
    assert position(d) == scan_steps
    # Object 1 was already in the library under another name: with "widget" taught from it, the two entries are
    # twins, and the match names widget (as best or runner-up; issue 27: ambiguous, so no label is taken).
    objects = scan["detections"]["objects"]
    taught = next(o["identification"] for o in objects if o["index"] == 1)
    assert "widget" in (taught["best"], taught["runner_up"]), taught
    other = next(o["label"] for o in objects if o["index"] != 1 and o["label"] not in (None, "widget"))
    events, r = ok(d, {"cmd": "pick", "name": other, "place": "bin"})
    planned = [e for e in events if e["event"] == "planned"][0]
    assert planned["place"] == "bin"
    # The background: the live (unchanged) scene as the empty table, so the next scan sees nothing.
    _, r = ok(d, {"cmd": "background", "frames": 3})
    assert r["frames"] == 3 and (state / "background.png").exists()
    _, scan = ok(d, {"cmd": "scan"})
    assert scan["objects"] == 0, scan["report"]
    d.stop()
    d = daemon_factory(sim.port, cfg)
    _, scan = ok(d, {"cmd": "scan"})
    assert scan["objects"] == 0  # still in force after a restart
    # A corrupt state file: the daemon refuses to start, naming it; nothing is overwritten.
    d.stop()
    (state / "places.json").write_text("{not json")
    r = subprocess.run([e2e.need(e2e.BIN / "rbx1d"), "--config", str(d.config), "--port", sim.port],
                       capture_output=True, text=True, timeout=20)
    assert r.returncode == 1 and "places.json: not a JSON object" in r.stderr, r.stderr
    assert (state / "places.json").read_text() == "{not json"
