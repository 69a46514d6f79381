"""test_workspace.py - the workspace calibration in simulation: ArUco markers rendered at known base-frame positions
(tools/markersim) through a camera whose mount differs from data/rbx1.toml's by a few mm and degrees; the tool point
jogged onto each marker's centre (the jog's own resolution) and recorded; the fit's error on markers it never saw
touched (held out) below 1 mm; a pick through the new calibration within 1 mm of the truth where the config's
hand-measured mount misses by the mount error. Bad input (too few, collinear, an off-centre touch, a touch in the
air, an unknown marker) and a cancelled calibration: clear errors, nothing moved, the old calibration kept."""
import json
import math
import shutil
import subprocess
import sys

import cv2

import rbx1e2e as e2e
from rbx1e2e import err, ok, position
from conftest import fast_config

sys.path.insert(0, str(e2e.ROOT / "tools" / "markersim"))
import markersim  # noqa: E402

SPOTS = [(340, 70), (340, 23), (340, -23), (340, -70), (250, 70), (250, 23), (250, -23), (250, -70), (295, 75),
         (295, -75)]
MARKERS = [(i, x, y, 24.0) for i, (x, y) in enumerate(SPOTS)]
HELD_OUT = (5, 6)  # seen by the camera, never touched: the fit's honest check
OBJECT = markersim.rectangle(295.0, 0.0, 40.0, 16.0, 60.0)
# The real camera: 3 / -2.5 / 4 mm and 0.8 / -0.6 / 1.5 deg away from what the config's mount describes.
TRUE_CAMERA = markersim.Camera((298.0, -2.5, 504.0), rot_deg=(0.8, -0.6, 1.5), focal_px=2000.0)
FIT_TOL_MM = 1.0
PICK_TOL_MM = 1.0


def calib(d, action, **kw):
    return d.request({"cmd": "calibrate_workspace", "action": action, **kw})[1]


def touch(d, arm, x, y, z=0.0):
    """Jogs the tool point to (x, y, z) mm: up to 30 mm, across, down. Returns where it ended (FK of the steps)."""
    (cx, cy, cz), _, _ = e2e.tool_pose(arm, position(d))
    if cz < 30:
        ok(d, {"cmd": "jog", "mm": [0, 0, 30 - cz]})
        cz = 30.0
    ok(d, {"cmd": "jog", "mm": [x - cx, y - cy, 0]})
    (cx, cy, cz), _, _ = e2e.tool_pose(arm, position(d))
    ok(d, {"cmd": "jog", "mm": [x - cx, y - cy, z - cz]})
    return e2e.tool_pose(arm, position(d))[0]


def pick_error(d, truth_xy, name):
    events, r = ok(d, {"cmd": "pick", "name": name, "place": "tray"})
    planned = [e for e in events if e["event"] == "planned"][0]
    g = planned["grasp"]
    return math.hypot(g["x_mm"] - truth_xy[0], g["y_mm"] - truth_xy[1]), g, planned["map"]


def test_calibration_from_touched_markers(sim, daemon_factory, tmp_path):
    empty, truth = markersim.render(TRUE_CAMERA, MARKERS)
    scene, _ = markersim.render(TRUE_CAMERA, MARKERS, [(OBJECT, 60)])
    cv2.imwrite(str(tmp_path / "empty.png"), empty)
    cv2.imwrite(str(tmp_path / "scene.png"), scene)
    arm = e2e.load_default_config()["arm"]
    cfg = fast_config()
    cfg["camera"]["device"] = str(tmp_path / "empty.png")
    cfg["vision"]["background"] = str(tmp_path / "empty.png")
    cfg["operator"] = {"jog_max_mm": 500.0, "max_rms_mm": 0.5, "max_loo_mm": 1.0}
    d = daemon_factory(sim.port, cfg)
    state = tmp_path / "state"

    # Start: every marker found, where the true camera puts it.
    _, r = ok(d, {"cmd": "calibrate_workspace", "action": "start"})
    assert [m["id"] for m in r["markers"]] == list(range(10))
    for m in r["markers"]:
        u, v = TRUE_CAMERA.project(*truth["markers"][m["id"]])
        assert math.hypot(m["centre_px"][0] - u, m["centre_px"][1] - v) < 0.3, (m, u, v)
    assert r["in_force"] == "mount"

    # Bad input, nothing moved: fit with nothing recorded, a touch in the air, an unknown marker.
    moves = len(sim.moves())
    e = err(d, {"cmd": "calibrate_workspace", "action": "fit"})
    assert e["code"] == "too_few_markers" and "old calibration stays" in e["message"], e
    e = err(d, {"cmd": "calibrate_workspace", "action": "record", "marker": 0})
    assert e["code"] == "not_on_table" and "above the table" in e["message"], e
    e = err(d, {"cmd": "calibrate_workspace", "action": "record", "marker": 42})
    assert e["code"] == "unknown_marker" and "seen: 0, 1, 2" in e["message"], e
    assert len(sim.moves()) == moves

    # Cancelled: the session is gone, nothing written.
    touch(d, arm, *truth["markers"][0])
    ok(d, {"cmd": "calibrate_workspace", "action": "record", "marker": 0})
    _, r = ok(d, {"cmd": "calibrate_workspace", "action": "cancel"})
    assert r == {"cancelled": True, "in_force": "mount"}
    assert err(d, {"cmd": "calibrate_workspace", "action": "record", "marker": 0})["code"] == "no_calibration"
    assert not (state / "workspace.json").exists()

    ok(d, {"cmd": "calibrate_workspace", "action": "start"})
    touched = {}
    # One column of markers: too few, then collinear.
    for i in (0, 1, 2):
        touched[i] = touch(d, arm, *truth["markers"][i])
        ok(d, {"cmd": "calibrate_workspace", "action": "record", "marker": i})
    assert err(d, {"cmd": "calibrate_workspace", "action": "fit"})["code"] == "too_few_markers"
    touched[3] = touch(d, arm, *truth["markers"][3])
    ok(d, {"cmd": "calibrate_workspace", "action": "record", "marker": 3})
    e = err(d, {"cmd": "calibrate_workspace", "action": "save"})
    assert e["code"] == "degenerate" and "collinear" in e["message"], e
    assert not (state / "workspace.json").exists()
    # An off-centre touch (5 mm): its leave-one-out error gives it away and the save is refused.
    for i in (4, 7, 8, 9):
        x, y = truth["markers"][i]
        touched[i] = touch(d, arm, x + (5.0 if i == 4 else 0.0), y)
        ok(d, {"cmd": "calibrate_workspace", "action": "record", "marker": i})
    _, fit = ok(d, {"cmd": "calibrate_workspace", "action": "fit"})
    assert not fit["accepted"], fit
    worst = max(fit["markers"], key=lambda m: m["loo_mm"])
    assert worst["id"] == 4 and worst["loo_mm"] > 3, fit["markers"]
    e = err(d, {"cmd": "calibrate_workspace", "action": "save"})
    assert e["code"] == "fit_rejected" and "nothing saved" in e["message"], e
    assert not (state / "workspace.json").exists()
    # Touched again, on the centre: accepted.
    touched[4] = touch(d, arm, *truth["markers"][4])
    ok(d, {"cmd": "calibrate_workspace", "action": "record", "marker": 4})
    for i, p in touched.items():  # the jog's resolution
        assert math.hypot(p[0] - truth["markers"][i][0], p[1] - truth["markers"][i][1]) < 0.1, (i, p)
        assert abs(p[2]) < 0.1
    _, fit = ok(d, {"cmd": "calibrate_workspace", "action": "fit"})
    assert fit["accepted"] and fit["model"] == "homography", fit
    held = {m["id"]: m["mm"] for m in fit["predicted"]}
    held_err = {i: math.hypot(held[i][0] - truth["markers"][i][0], held[i][1] - truth["markers"][i][1]) for i in HELD_OUT}
    print(f"\nfit over {len(fit['markers'])} markers: RMS {fit['rms_mm']:.3f} mm, worst leave-one-out "
          f"{fit['max_loo_mm']:.3f} mm; per marker (residual, LOO): "
          + ", ".join(f"{m['id']}: {m['residual_mm']:.3f}/{m['loo_mm']:.3f}" for m in fit["markers"])
          + "; held out: " + ", ".join(f"{i}: {e:.3f} mm" for i, e in held_err.items()))
    assert fit["rms_mm"] < 0.5 and fit["max_loo_mm"] < FIT_TOL_MM
    assert max(held_err.values()) < FIT_TOL_MM, held_err
    _, saved = ok(d, {"cmd": "calibrate_workspace", "action": "save"})
    assert saved["in_force"] == "workspace" and saved["saved"] == str(state / "workspace.json")
    on_disk = json.loads((state / "workspace.json").read_text())
    assert on_disk["format"] == "rbx1-workspace" and len(on_disk["points"]) == 8
    assert calib(d, "status")["result"] == {"active": False, "in_force": "workspace"}
    # The guided CLI: every marker skipped, the fit refused, the session cancelled; the saved calibration stays.
    saved_bytes = (state / "workspace.json").read_bytes()
    r = subprocess.run([e2e.need(e2e.BIN / "rbx1"), "calibrate-workspace", "--socket", d.socket], input="s\n" * 10,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 1, (r.stdout, r.stderr)
    assert "10 markers seen at the scan pose: 0 1 2 3 4 5 6 7 8 9" in r.stdout, r.stdout
    assert "too_few_markers" in r.stderr and "cancelled; the old calibration stays in force" in r.stdout, r
    assert calib(d, "status")["result"] == {"active": False, "in_force": "workspace"}
    assert (state / "workspace.json").read_bytes() == saved_bytes
    # The empty table at the scan pose for every later scan.
    ok(d, {"cmd": "background", "frames": 2})
    d.stop()

    # A restart on the scene with the object: taught from the camera, picked through the new calibration.
    cfg["camera"]["device"] = str(tmp_path / "scene.png")
    old_state = tmp_path / "state_old"
    d = daemon_factory(sim.port, cfg)
    _, scan = ok(d, {"cmd": "scan"})
    assert scan["objects"] == 1, scan["report"]
    ok(d, {"cmd": "teach", "index": 1, "name": "bar"})
    shutil.copytree(state, old_state)
    (old_state / "workspace.json").unlink()
    truth_xy = (295.0, 0.0)
    new_err, g, used = pick_error(d, truth_xy, "bar")
    assert used == "workspace"
    assert e2e.axis_diff(g["yaw_deg"], 60.0 + 90.0) < 1.0, g  # the fingers close across the bar
    d.stop()

    # The same pick through the config's hand-measured mount (same background and library, no workspace.json).
    cfg["daemon"]["state_dir"] = str(old_state)
    d = daemon_factory(sim.port, cfg)
    old_err, g_old, used = pick_error(d, truth_xy, "bar")
    assert used == "mount"
    print(f"pick error: workspace calibration {new_err:.3f} mm, config mount {old_err:.3f} mm")
    assert new_err < PICK_TOL_MM, (new_err, g)
    assert old_err > 3.0, (old_err, g_old)


def test_marker_sheet_cli(tmp_path):
    rbx1 = e2e.need(e2e.BIN / "rbx1")
    r = subprocess.run([rbx1, "markers", "--out", str(tmp_path / "s.pdf"), "--ids", "0", "1", "2", "3"],
                       capture_output=True, text=True, timeout=30)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "s.pdf").read_bytes().startswith(b"%PDF-1.4")
    r = subprocess.run([rbx1, "markers", "--out", str(tmp_path / "s.png"), "--dpi", "100"], capture_output=True,
                       text=True, timeout=30)
    assert r.returncode == 0, r.stderr
    img = cv2.imread(str(tmp_path / "s.png"), cv2.IMREAD_GRAYSCALE)
    assert img.shape == (1169, 827)  # A4 at 100 dpi
    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    _, ids, _ = cv2.aruco.detectMarkers(img, d)
    assert sorted(ids.ravel().tolist()) == [0, 1, 2, 3, 4, 5]
    for bad in (["--out", str(tmp_path / "s.txt")], ["--out", str(tmp_path / "t.pdf"), "--ids", "77"],
                ["--out", str(tmp_path / "nodir" / "t.pdf")]):
        r = subprocess.run([rbx1, "markers", *bad], capture_output=True, text=True, timeout=30)
        assert r.returncode == 2 and r.stderr.count("\n") == 1 and r.stderr.startswith("rbx1: markers: "), r.stderr
