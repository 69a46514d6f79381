"""test_newuser.py - a new user's first session from the web console alone (headless Chromium, Selenium), against
rbx1d and rbx1-simfw with the bundled config as installed (its [operator] defaults: jogs of at most 50 mm): save a
scan pose, calibrate the workspace through the guided sequence (markers laid on the table, the tool point jogged onto
each with the page's buttons, Record, Fit, Save), save a place, capture the empty table, teach an object by clicking
it in the scan, pick it to that place, and press E-STOP during a second pick. No CLI, no TOML edits: every request
comes from a click or a typed field. The camera looks at the table from a stand, 3 / -2.5 / 4 mm and 0.8 / -0.6 /
1.5 deg away from what [arm.camera] says (tools/markersim renders what it sees); the test changes what lies on
the table (the camera is a folder holding one image, replaced atomically) and judges positions by eye (forward
kinematics of the firmware's step counts). Each step's result is checked in the page (log lines, messages, tables),
in the state directory and in the firmware's executed moves. Screenshots: build/e2e/newuser/."""
import json
import math
import os
import sys
import time

import cv2
import numpy as np
import pytest
from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By

import rbx1e2e as e2e
from consolepage import last_seq, log_entries, status_row, wait
from conftest import fast_config

sys.path.insert(0, str(e2e.ROOT / "tools" / "markersim"))
import markersim  # noqa: E402

SHOTS = e2e.ROOT / "build" / "e2e" / "newuser"
TRUE_CAMERA = markersim.Camera((298.0, -2.5, 504.0), rot_deg=(0.8, -0.6, 1.5), focal_px=2000.0)
# Touched in the order the page proposes (0..5), each one jog across from the last; 6 and 7 are seen but never
# touched: the held-out check (one inside the touched ones, one beyond them).
SPOTS = [(335, 50), (335, 0), (335, -50), (290, -50), (245, -50), (245, 0), (290, 10), (245, 60)]
MARKERS = [(i, x, y, 24.0) for i, (x, y) in enumerate(SPOTS)]
TOUCHED = 6
BAR = (300.0, 20.0)  # the object's centre (mm), a 40 x 16 mm bar turned 60 deg
OBJECT = markersim.rectangle(BAR[0], BAR[1], 40.0, 16.0, 60.0)
SHELF = (200.0, 150.0, 20.0)  # where the user puts the place: a shelf 20 mm high
TOUCH_Z_MM = 0.2   # the fingertips just on the marker
EYE_TOL_MM = 0.15  # what the user's eye tells apart
JOG_MAX_MM = 50.0  # data/rbx1.toml [operator] jog_max_mm


class Table:
    """What lies on the table, as the camera sees it: one image in the camera's folder, replaced atomically."""

    def __init__(self, tmp):
        self.dir = tmp / "camera"
        self.dir.mkdir()
        self.spare = tmp / "next.png"

    def show(self, markers=(), objects=()):
        img, truth = markersim.render(TRUE_CAMERA, markers, objects)
        cv2.imwrite(str(self.spare), img)
        os.replace(self.spare, self.dir / "table.png")
        return truth


@pytest.fixture
def cell(tmp_path):
    table = Table(tmp_path)
    table.show()
    cfg = fast_config()
    cfg["camera"]["device"] = str(table.dir)
    cfg["vision"]["background"] = ""  # a fresh install has no picture of this table yet
    sim = e2e.Simfw(tmp_path, "--eeprom", tmp_path / "eeprom.bin")
    e2e.configure_fast_firmware(sim.port)
    d = e2e.Daemon(tmp_path, cfg, sim.port)
    opts = webdriver.ChromeOptions()
    opts.binary_location = e2e.need("/usr/bin/chromium")
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              "--window-size=1400,2000", "--user-data-dir=" + str(tmp_path / "chromium")):
        opts.add_argument(a)
    try:
        drv = webdriver.Chrome(service=Service(e2e.need("/usr/bin/chromedriver")), options=opts)
    except BaseException:
        d.stop()
        sim.stop()
        raise
    drv.set_page_load_timeout(20)
    SHOTS.mkdir(parents=True, exist_ok=True)
    yield table, sim, d, drv, tmp_path / "state"
    drv.quit()
    d.stop()
    sim.stop()





FINAL = """
    const [after, cmd, sel] = arguments;
    const li = [...document.querySelectorAll('#log li')].find(li => li.value > after && li.dataset.cmd === cmd &&
                                                                     ['result', 'error'].includes(li.dataset.event));
    return li && !document.querySelector(sel).disabled ? [li.dataset.event, li.textContent, li.title] : null;"""


def click(drv, selector, cmd, timeout=60):
    """Clicks a button whose request is cmd; returns (event, text, whole JSON line) of the request's final log line
    once the page took the reply (the button enabled again)."""
    base = last_seq(drv)
    drv.find_element(By.CSS_SELECTOR, selector).click()
    return wait(drv, lambda b: b.execute_script(FINAL, base, cmd, selector), timeout, f"{selector}: no reply to {cmd}")


def result(drv, selector, cmd, timeout=60):
    """The result of a request that must succeed: its log line's whole JSON (the line's title)."""
    e, t, line = click(drv, selector, cmd, timeout)
    assert e == "result", t
    return json.loads(line)["result"]


def type_into(drv, element_id, text):
    el = drv.find_element(By.ID, element_id)
    el.clear()
    el.send_keys(str(text))



def tool(d, arm):
    """Where the tool point is: the user's eye (forward kinematics of the firmware's step counts)."""
    return e2e.tool_pose(arm, e2e.status(d)["firmware"]["position"])


def jog_axis(drv, axis, delta):
    """Moves the tool point along one base axis with the page's buttons: the amount typed, +/- clicked, in jogs of
    at most jog_max_mm."""
    jogs = 0
    while abs(delta) > 1e-3:
        step = max(-JOG_MAX_MM, min(JOG_MAX_MM, delta))
        field = drv.find_element(By.ID, "jog-mm")
        if field.get_attribute("value") != f"{abs(step):.3f}":  # the amount stays typed from the last jog
            field.clear()
            field.send_keys(f"{abs(step):.3f}")
        sign = 1 if step > 0 else -1
        result(drv, f"button.jog-mm[data-axis='{axis}'][data-sign='{sign}']", "jog")
        delta -= float(f"{step:.3f}")
        jogs += 1
    return jogs


def jog_to(drv, d, arm, target, lift=True):
    """To 30 mm above the table (up when lower, down first when higher: the wrist reaches further there), across,
    down; then corrections until the eye sees it there."""
    jogs = 0
    (x, y, z), _, _ = tool(d, arm)
    if (lift and z < 30) or z > 30:
        jogs += jog_axis(drv, 2, 30 - z)
    for _ in range(4):
        (x, y, z), _, _ = tool(d, arm)
        d_xyz = [target[0] - x, target[1] - y, target[2] - z]
        if max(abs(v) for v in d_xyz) <= EYE_TOL_MM:
            return jogs
        for axis in (0, 1, 2):
            if abs(d_xyz[axis]) > EYE_TOL_MM / 2:
                jogs += jog_axis(drv, axis, d_xyz[axis])
    raise AssertionError(f"the tool point never reached {target}: at {tool(d, arm)[0]}")


def calib_out(drv):
    return drv.find_element(By.ID, "calib-out").text



def rows(drv):
    return drv.execute_script(
        "return [...document.querySelectorAll('#objects tbody tr')].map(tr => [tr.className, ...[...tr.cells].map(c => c.textContent)])")


def scan(drv, objects):
    """Scan from the page; waits until the objects table and the picture show this scan."""
    before = drv.execute_script("return state.lastScan")
    r = result(drv, "#scan", "scan")
    wait(drv, lambda b: b.execute_script("return state.lastScan") > before and len(rows(b)) == objects, 30,
         "the objects table never showed the scan")
    wait(drv, lambda b: b.execute_script(
        "const i = document.getElementById('view'); return !i.hidden && i.complete && i.naturalWidth > 0 && "
        "i.src.includes('n=' + state.lastScan)"), 30, "the scan's picture never loaded")
    return r


def test_new_user_from_the_console_alone(cell):
    table, sim, d, drv, state = cell
    try:
        first_session(table, sim, d, drv, state)
    except BaseException:
        drv.save_screenshot(str(SHOTS / "failed.png"))
        print("the page's message:", drv.find_element(By.ID, "message").text)
        print("the page's last log lines:\n" + "\n".join(t for _, _, t in log_entries(drv)[-25:]))
        raise


def first_session(table, sim, d, drv, state):
    arm = e2e.load_default_config()["arm"]
    t0 = time.monotonic()
    phases = {}
    drv.get(d.console_url())
    wait(drv, lambda b: b.find_element(By.ID, "state").text == "ready", 30, "the page never showed ready")
    for panel in ("jog-panel", "teach-panel", "calib-panel"):
        assert drv.find_element(By.ID, panel).is_displayed(), panel
    assert drv.find_element(By.ID, "view-empty").text == "no scan yet: press Scan"
    assert (status_row(drv, "calibration") or "").startswith("mount"), status_row(drv, "calibration")

    # 1. The scan pose: Scan takes the arm to the installed one (the empty table: nothing found), the user raises it
    # 10 mm and saves it.
    scan(drv, 0)
    jog_axis(drv, 2, 10.0)
    here = e2e.status(d)  # joints rounded to 0.01 deg
    saved = result(drv, "#pose-save", "pose_save")
    poses = json.loads((state / "poses.json").read_text())
    assert saved["pose"] == "scan" and "warning" not in saved, saved
    assert poses["scan"] == pytest.approx(here["joints_deg"], abs=0.006), (poses, here["joints_deg"])
    scan_steps = here["firmware"]["position"]
    phases["scan pose"] = time.monotonic() - t0

    # 2. The workspace calibration: the marker sheet on the table, Start at the (new) scan pose.
    truth = table.show(MARKERS)
    result(drv, "#calib-start", "calibrate_workspace")
    assert e2e.status(d)["firmware"]["position"] == scan_steps, "Start did not go to the saved scan pose"
    assert calib_out(drv).startswith("8 markers seen: 0 1 2 3 4 5 6 7"), calib_out(drv)
    jogs = 0
    for n in range(TOUCHED):
        want = drv.find_element(By.ID, "calib-marker").get_attribute("value")
        assert want == str(n), (n, want)  # the page proposes the next marker to touch
        mx, my = truth["markers"][n]
        jogs += jog_to(drv, d, arm, (mx, my, TOUCH_Z_MM))
        rec = result(drv, "#calib-record", "calibrate_workspace")
        assert rec["marker"] == n and rec["recorded"] == n + 1, rec
        assert math.hypot(rec["mm"][0] - mx, rec["mm"][1] - my) < EYE_TOL_MM * 1.5, (rec, mx, my)
        assert f"marker {n} recorded at" in calib_out(drv), calib_out(drv)
    assert "left to touch: 6 7" in calib_out(drv), calib_out(drv)
    jogs += jog_axis(drv, 2, 30.0)
    fit = result(drv, "#calib-fit", "calibrate_workspace")
    assert fit["accepted"] and fit["model"] == "homography" and len(fit["markers"]) == TOUCHED, fit
    out = calib_out(drv)
    assert out.startswith(f"homography over {TOUCHED} markers: RMS {fit['rms_mm']:.3f} mm"), out
    assert "accepted: Save to use it" in out and "leave-one-out (mm)" in out, out
    drv.save_screenshot(str(SHOTS / "1-calibration-fit.png"))
    saved = result(drv, "#calib-save", "calibrate_workspace")
    assert saved["in_force"] == "workspace" and saved["saved"] == str(state / "workspace.json"), saved
    assert "saved to " + str(state / "workspace.json") + ": in force" in calib_out(drv), calib_out(drv)
    wait(drv, lambda b: (status_row(b, "calibration") or "").startswith(
        f"workspace: homography over {TOUCHED} markers, RMS {fit['rms_mm']:.3f} mm"), 10,
        "the arm table does not show the new calibration")
    ws = json.loads((state / "workspace.json").read_text())
    assert ws["format"] == "rbx1-workspace" and len(ws["points"]) == TOUCHED, ws
    # Its error where nobody touched: the held-out markers' pixels (as the true camera sees them) through the map.
    h = np.array(ws["homography"])
    held = {}
    for i in range(TOUCHED, len(MARKERS)):
        u, v = TRUE_CAMERA.project(*truth["markers"][i])
        p = h @ np.array([u, v, 1.0])
        held[i] = math.hypot(p[0] / p[2] - truth["markers"][i][0], p[1] / p[2] - truth["markers"][i][1])
    print(f"\ncalibration from the page: {TOUCHED} markers touched with {jogs} jogs, RMS {fit['rms_mm']:.3f} mm, "
          f"worst leave-one-out {fit['max_loo_mm']:.3f} mm, table at z {fit['table_z_mm']:.3f} mm; held out: "
          + ", ".join(f"marker {i} {e:.3f} mm" for i, e in held.items()))
    assert fit["rms_mm"] < 0.5 and fit["max_loo_mm"] < 1.0, fit
    assert max(held.values()) < 1.0, held
    phases["calibration"] = time.monotonic() - t0

    # 3. A place: the fingertips on the shelf's surface, named, saved; the pick form offers it.
    jog_to(drv, d, arm, SHELF)
    type_into(drv, "place-name", "shelf")
    place = result(drv, "#place-save", "place_save")
    places = json.loads((state / "places.json").read_text())
    for got in (place, places["shelf"]):
        assert math.dist((got["x_mm"], got["y_mm"], got["z_mm"]), SHELF) < EYE_TOL_MM * 1.5, got
    wait(drv, lambda b: "shelf" in b.execute_script(
        "return [...document.querySelectorAll('#places option')].map(o => o.value)"), 10, "the place list lacks it")
    jog_axis(drv, 2, 40.0)
    phases["place"] = time.monotonic() - t0

    # 4. The empty table, captured at the scan pose.
    table.show()
    bg = result(drv, "#background", "background")
    assert bg["background"] == str(state / "background.png") and bg["frames"] == 8, bg
    assert cv2.imread(str(state / "background.png")).shape == (600, 800, 3)
    assert e2e.status(d)["firmware"]["position"] == scan_steps
    phases["background"] = time.monotonic() - t0

    # 5. The object on the table: Scan, click it in the picture, name it, Teach; the next scan knows it.
    truth = table.show(objects=[(OBJECT, 60)])
    scan(drv, 1)
    img = drv.find_element(By.ID, "view")
    u, v = TRUE_CAMERA.project(*BAR)
    size = drv.execute_script("const i = arguments[0]; return [i.clientWidth, i.clientHeight, i.naturalWidth, i.naturalHeight]", img)
    dx, dy = u * size[0] / size[2] - size[0] / 2, v * size[1] / size[3] - size[1] / 2
    ActionChains(drv).move_to_element_with_offset(img, round(dx), round(dy)).click().perform()
    wait(drv, lambda b: rows(b)[0][0] == "selected", 10, "the click on the object did not select it")
    type_into(drv, "teach-name", "bar")
    taught = result(drv, "#teach", "teach")
    assert taught["taught"] == "bar" and taught["library"] == str(state / "library.json"), taught
    lib = json.loads((state / "library.json").read_text())
    assert "bar" in json.dumps(lib), "bar is not in the state library"
    scan(drv, 1)
    row = rows(drv)[0]
    assert row[2] == "bar" and float(row[3]) > 0.95, row
    drv.save_screenshot(str(SHOTS / "2-taught.png"))
    phases["teach"] = time.monotonic() - t0

    # 6. Pick it to the shelf: its row clicked, the place typed, Pick.
    drv.find_elements(By.CSS_SELECTOR, "#objects tbody tr")[0].click()
    assert drv.find_element(By.ID, "pick-name").get_attribute("value") == "bar"
    type_into(drv, "pick-place", "shelf")
    before = len(sim.moves())
    base = last_seq(drv)
    picked = result(drv, "#pick", "pick", timeout=120)
    assert picked["picked"] == "bar", picked
    names = [e for e, c, _ in log_entries(drv, base) if c == "pick"]
    for needed in ("request", "captured", "detected", "identified", "planned", "step_done", "result"):
        assert needed in names, names
    planned = next(t for e, c, t in log_entries(drv, base) if c == "pick" and e == "planned")
    assert 'map="workspace"' in planned, planned
    # The firmware's executed entries: open, close (the grasp), release (at the shelf); where the tool was.
    log = sim.moves()[before:]
    grippers = [k for k, e in enumerate(log) if e["kind"] == "gripper"]
    assert len(grippers) == 3, [e["kind"] for e in log]
    grasp = e2e.tool_pose(arm, log[grippers[1] - 1]["end"])[0]
    release = e2e.tool_pose(arm, log[grippers[2] - 1]["end"])[0]
    grasp_err = math.hypot(grasp[0] - truth["objects"][0][0], grasp[1] - truth["objects"][0][1])
    release_err = math.hypot(release[0] - places["shelf"]["x_mm"], release[1] - places["shelf"]["y_mm"])
    print(f"pick from the page: grasp {grasp_err:.3f} mm from the bar's true centre, release {release_err:.3f} mm "
          f"from the saved shelf (x, y), at z {release[2]:.2f} mm over a shelf at {places['shelf']['z_mm']:.2f} mm")
    assert grasp_err < 1.0, (grasp, truth["objects"])
    assert release_err < 0.2 and release[2] > places["shelf"]["z_mm"], (release, places["shelf"])
    assert e2e.status(d)["firmware"]["position"] == [0] * 6  # home
    wait(drv, lambda b: b.find_element(By.ID, "message").text == "pick: done", 20)
    drv.save_screenshot(str(SHOTS / "3-picked.png"))
    phases["pick"] = time.monotonic() - t0

    # 7. E-STOP while the next pick carries its part; the fault shown, cleared from the page, home.
    base = last_seq(drv)
    drv.find_element(By.ID, "pick").click()
    drv.set_script_timeout(90)
    drv.execute_async_script("""
        const base = arguments[0], done = arguments[arguments.length - 1];
        const timer = setInterval(() => {
          const lines = [...document.querySelectorAll('#log li')].filter((li) => li.value > base);
          if (lines.some((li) => li.dataset.event === 'step' && li.textContent.includes('name="carry"'))) {
            clearInterval(timer);
            document.getElementById('estop').click();
            done(true);
          }
        }, 10);""", base)
    wait(drv, lambda b: any(e == "error" and c == "pick" and "estop" in t for e, c, t in log_entries(b, base)), 30,
         "the pick never ended with the e-stop")
    assert not any(e == "result" and c == "pick" for e, c, _ in log_entries(drv, base)), "the pick completed"
    wait(drv, lambda b: b.find_element(By.ID, "state").text == "fault", 10, "the page does not show the fault")
    fw = e2e.status(d)["firmware"]
    assert fw["state"] == "FAULT" and "ESTOP_COMMAND" in fw["faults"] and fw["position"] != [0] * 6, fw
    still = fw["position"]
    wait(drv, lambda b: "latched" in b.find_element(By.ID, "message").text, 10, "no e-stop confirmation")
    drv.save_screenshot(str(SHOTS / "4-estop.png"))
    assert e2e.status(d)["firmware"]["position"] == still, "the arm moved after the e-stop"
    result(drv, "#clear-fault", "clear_fault")
    result(drv, "#home", "home")
    wait(drv, lambda b: b.find_element(By.ID, "state").text == "ready", 20)
    assert e2e.status(d)["firmware"]["position"] == [0] * 6
    phases["e-stop"] = time.monotonic() - t0
    print("cumulative seconds: " + ", ".join(f"{k} {v:.1f}" for k, v in phases.items()))
