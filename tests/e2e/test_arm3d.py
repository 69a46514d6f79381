"""test_arm3d.py - the console's 3D view (host/console/www/arm3d.js) in headless Chromium against rbx1d and
rbx1-simfw: three.js is Debian's libjs-three served by rbx1d (nothing from a network); the arm drawn from the
daemon's URDF shows the joint angles of `status`; a jog from the page changes the rendered arm where the arm is
(two screenshots); the camera's view at the scan pose and the scanned objects lie where the map in force puts them
(checked against this file's own kinematics and the pick's grasp); a pick's planned tool path is drawn before its
first move ends. One browser and one daemon for the file; screenshots go to build/e2e/arm3d/."""
import json
import subprocess
import threading
import urllib.request
from datetime import datetime
from pathlib import Path

import cv2
import numpy as np
import pytest
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select

import rbx1e2e as e2e
from consolepage import chromium, wait
from conftest import fast_config

SHOTS = e2e.ROOT / "build" / "e2e" / "arm3d"
THREE = Path("/usr/share/javascript/three")


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("arm3d")
    sim = e2e.Simfw(tmp, "--eeprom", tmp / "eeprom.bin")
    e2e.configure_fast_firmware(sim.port)
    cfg = fast_config()
    cfg["console"] = {"bind": "127.0.0.1:0"}
    cfg["operator"] = {"jog_max_deg": 30.0}  # one jog of the shoulder that moves the picture plainly
    d = e2e.Daemon(tmp, cfg, sim.port)
    yield cfg, d, d.console_url()
    d.stop()
    sim.stop()


@pytest.fixture(scope="module")
def browser(rig):
    drv = chromium(rig[1].log_path.parent / "chromium", 1400, 1400)
    drv.set_page_load_timeout(30)  # three.js is 600 kB
    drv.get(rig[2])
    SHOTS.mkdir(parents=True, exist_ok=True)
    yield drv
    drv.quit()


def api(url, path, body=None):
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url.rstrip("/") + path, data=data, headers={"Content-Type": "application/json"})
    with urllib.request.urlopen(req, timeout=180) as r:
        return json.loads(r.read())


def drawn(drv):
    """The joint angles of the last frame the page rendered (None before the first)."""
    j = drv.execute_script("return document.getElementById('arm3d').dataset.joints || null")
    return json.loads(j) if j else None


def wait_drawn_is_status(drv, url, msg):
    """Until the page has drawn exactly the joints of `status` (GET /api/status); returns them."""
    def same(d):
        want = api(url, "/api/status")["result"]["joints_deg"]
        return want if drawn(d) == want else None
    return wait(drv, same, 30, msg)


def shot(drv, name):
    """A screenshot of the 3D view alone (build/e2e/arm3d/NAME), as a BGR image."""
    path = SHOTS / name
    canvas = drv.find_element(By.ID, "arm3d").find_element(By.TAG_NAME, "canvas")
    drv.execute_script("arguments[0].scrollIntoView({block: 'end'})", canvas)  # whole, clear of the sticky header
    canvas.screenshot(str(path))
    return cv2.imread(str(path))


def test_three_js_is_debians_and_nothing_comes_from_a_network(rig, browser):
    _, _, url = rig
    for route, path in (("/three.js", THREE / "three.min.js"),
                        ("/three-orbit.js", THREE / "examples/js/controls/OrbitControls.js")):
        with urllib.request.urlopen(url.rstrip("/") + route, timeout=10) as r:
            assert r.read() == path.read_bytes(), route
    wait(browser, lambda d: drawn(d), 30, "the 3D view never drew the arm")
    origin = url.rstrip("/")
    loaded = browser.execute_script("return performance.getEntriesByType('resource').map(e => e.name)")
    assert any(n.endswith("/three.js") for n in loaded)
    assert all(n.startswith(origin) for n in loaded), [n for n in loaded if not n.startswith(origin)]
    # The URDF it drew is the daemon's (`rbx1 urdf` of the same config).
    urdf = api(url, "/api/scene")["result"]["urdf"]
    cli = subprocess.run([e2e.need(e2e.BIN / "rbx1"), "urdf", "--config", str(rig[1].config)],
                         capture_output=True, text=True, check=True).stdout
    assert urdf == cli
    links = browser.execute_script("return ['base_link','link_3','tool0','camera_optical'].map(n => arm3d.screen(n))")
    assert all(p is not None for p in links), links


def test_the_drawn_arm_follows_a_jog_from_the_page(rig, browser):
    _, _, url = rig
    before = wait_drawn_is_status(browser, url, "the page never drew the status's joints")
    a = shot(browser, "1-before-jog.png")
    tool_a = browser.execute_script("return arm3d.screen('tool0')")
    # Jog J2 (the shoulder) by 30 degrees from the page's own jog panel.
    wait(browser, lambda d: d.find_element(By.ID, "jog-panel").is_displayed(), 20, "no jog panel")
    Select(browser.find_element(By.ID, "jog-joint")).select_by_visible_text("2")
    deg = browser.find_element(By.ID, "jog-deg")
    deg.clear()
    deg.send_keys("30")
    browser.find_element(By.ID, "jog-plus").click()
    wait(browser, lambda d: abs(api(url, "/api/status")["result"]["joints_deg"][1] - before[1] - 30) < 0.05, 60,
         "the jog did not move J2 by 30 degrees")
    after = wait_drawn_is_status(browser, url, "the page did not draw the jogged joints")
    assert after[1] == pytest.approx(before[1] + 30, abs=0.05) and after[0] == before[0]
    b = shot(browser, "2-after-jog.png")
    tool_b = browser.execute_script("return arm3d.screen('tool0')")
    assert a.shape == b.shape
    changed = (cv2.absdiff(a, b).max(axis=2) > 30).astype(np.uint8)
    ys, xs = np.nonzero(changed)
    print(f"3D view: {len(xs)} pixels changed in x {xs.min()}..{xs.max()}, y {ys.min()}..{ys.max()} of "
          f"{a.shape[1]}x{a.shape[0]}; tool0 drawn at {tool_a} then {tool_b}")
    assert len(xs) > 500, "the jog changed almost nothing in the picture"
    # The change is where the arm is: the tool point's old and new places lie in it, the table's far corners not.
    assert np.hypot(tool_a[0] - tool_b[0], tool_a[1] - tool_b[1]) > 20
    h, w = changed.shape
    for x, y in (tool_a, tool_b):
        assert 0 <= x < w and 0 <= y < h, f"the tool point is drawn off the view, at ({x:.0f}, {y:.0f})"
        near = changed[max(0, int(y) - 12):int(y) + 12, max(0, int(x) - 12):int(x) + 12]
        assert near.any(), f"nothing changed near the tool point drawn at ({x:.0f}, {y:.0f})"
    assert not changed[:h // 8, :w // 8].any() and not changed[-h // 8:, -w // 8:].any()
    e2e.ok(rig[1], {"cmd": "home"})


def test_scan_objects_view_and_the_planned_path(rig, browser):
    cfg, d, url = rig
    arm = cfg["arm"]
    browser.execute_script("arguments[0].click()", browser.find_element(By.ID, "scan"))  # under the sticky header
    wait(browser, lambda dr: int(dr.execute_script("return document.getElementById('arm3d').dataset.objects || 0")) > 0,
         60, "the scan's objects never appeared in the 3D view")
    scene = api(url, "/api/scene")["result"]
    scan = api(url, "/api/scan")["detections"]
    assert scene["map"] == "mount" and len(scene["objects"]) == len(scan["objects"])
    # The camera at the scan pose and its frame's corners on the table, computed here independently.
    apex = e2e.fk(arm, arm["poses"]["scan"])
    assert scene["view"]["apex_mm"] == pytest.approx([apex[0][3], apex[1][3], apex[2][3]], abs=0.01)
    w, h, ppc = scan["image"]["width"], scan["image"]["height"], scan["px_per_cm"]
    for corner, (u, v) in zip(scene["view"]["corners_mm"], ((0, 0), (w, 0), (w, h), (0, h))):
        (x, y), _ = e2e.vision_to_base(arm, (u / ppc, v / ppc), 0)
        assert corner[:2] == pytest.approx([x, y], abs=0.01)
    for o, s in zip(scan["objects"], scene["objects"]):
        (x, y), yaw = e2e.vision_to_base(arm, o["centroid_cm"], o["grip"]["angle_deg"])
        assert [s["x_mm"], s["y_mm"]] == pytest.approx([x, y], abs=0.01) and e2e.axis_diff(s["yaw_deg"], yaw) < 0.01
    shot(browser, "3-scan.png")

    # A pick: the page draws its planned tool path on the "planned" event, before the first move is done.
    label = e2e.scene_labels()[0]
    reply = {}
    t = threading.Thread(target=lambda: reply.update(api(url, "/api/pick", {"name": label, "place": "tray"})))
    t.start()
    wait(browser, lambda dr: int(dr.execute_script("return document.getElementById('arm3d').dataset.path || 0")) > 0,
         60, "no planned path drawn")
    shot(browser, "4-planned-path.png")
    t.join(180)
    assert "result" in reply, reply
    planned = next(e for e in reply["events"] if e.get("event") == "planned")
    moves = [wp["tool_mm"] for wp in planned["waypoints"] if wp["kind"] == "move"]
    assert browser.execute_script("return arm3d.path") == moves
    # Each tool point is the forward kinematics of its waypoint's steps (this file's own chain).
    for wp in planned["waypoints"]:
        if wp["kind"] == "move":
            (x, y, z), _, _ = e2e.tool_pose(arm, wp["target"])
            assert wp["tool_mm"] == pytest.approx([x, y, z], abs=0.01)
    # Drawn before the plan's first move ended (the firmware's first step_done after the planned event).
    after = reply["events"][reply["events"].index(planned):]
    first_done = next(e for e in after if e.get("event") == "step_done")
    done_ms = datetime.fromisoformat(first_done["ts"].replace("Z", "+00:00")).timestamp() * 1000
    drawn_ms = browser.execute_script("return arm3d.path_drawn_ms")
    assert drawn_ms < done_ms, (drawn_ms, first_done["ts"])
    # The object it picked lies in the view where the pick's grasp is (the same map).
    index = next(e for e in reply["events"] if e.get("event") == "identified")["index"]
    obj = next(o for o in scene["objects"] if o["index"] == index)
    assert [obj["x_mm"], obj["y_mm"]] == pytest.approx([planned["grasp"]["x_mm"], planned["grasp"]["y_mm"]], abs=0.01)
    wait_drawn_is_status(browser, url, "the page did not draw the arm where the pick left it")
    shot(browser, "5-after-pick.png")
