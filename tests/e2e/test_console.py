"""test_console.py - the web console in headless Chromium (Selenium, Debian's chromium-driver) against rbx1d and
rbx1-simfw: the page shows the annotated scan and the objects, a pick from the page runs to the end with its
events shown, the e-stop button latches the firmware's e-stop while the page's pick request still waits, and bad
requests (token, malformed) move nothing. One browser and one daemon for the whole file; screenshots go to
build/e2e/console/."""
import json
import os
import subprocess
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

import rbx1e2e as e2e
from conftest import fast_config

TOKEN = "console-test-token-0123456789"
SHOTS = e2e.ROOT / "build" / "e2e" / "console"


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("console")
    sim = e2e.Simfw(tmp, "--eeprom", tmp / "eeprom.bin")
    e2e.configure_fast_firmware(sim.port)
    cfg = fast_config()
    cfg["console"] = {"bind": "127.0.0.1:0", "token": TOKEN}
    d = e2e.Daemon(tmp, cfg, sim.port)
    yield sim, d, d.console_url()
    d.stop()
    sim.stop()


@pytest.fixture(scope="module")
def browser(rig):
    opts = webdriver.ChromeOptions()
    opts.binary_location = e2e.need("/usr/bin/chromium")
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              "--window-size=1400,1100", "--user-data-dir=" + str(rig[1].log_path.parent / "chromium")):
        opts.add_argument(a)
    drv = webdriver.Chrome(service=Service(e2e.need("/usr/bin/chromedriver")), options=opts)
    drv.set_page_load_timeout(20)
    drv.get(rig[2])
    token = drv.find_element(By.ID, "token")
    token.send_keys(TOKEN)
    drv.execute_script("arguments[0].dispatchEvent(new Event('change'))", token)
    SHOTS.mkdir(parents=True, exist_ok=True)
    yield drv
    drv.quit()


def wait(drv, what, timeout=60, msg=""):
    return WebDriverWait(drv, timeout, poll_frequency=0.1).until(lambda d: what(d), msg)


def log_entries(drv):
    """The event log as (event, cmd, text) per line."""
    return drv.execute_script(
        "return [...document.querySelectorAll('#log li')].map(li => [li.dataset.event, li.dataset.cmd, li.textContent])")


def rows(drv):
    return drv.execute_script(
        "return [...document.querySelectorAll('#objects tbody tr')].map(tr => [...tr.cells].map(c => c.textContent))")


def status(d):
    return d.request({"cmd": "status"})[1]["result"]


def http(url, body=None, token=None, ctype="application/json"):
    req = urllib.request.Request(url, data=None if body is None else body.encode(), method="GET" if body is None else "POST")
    if body is not None:
        req.add_header("Content-Type", ctype)
    if token:
        req.add_header("Authorization", "Bearer " + token)
    try:
        with urllib.request.urlopen(req, timeout=30) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def test_page_shows_scan_and_objects(rig, browser):
    _, d, _ = rig
    wait(browser, lambda b: b.find_element(By.ID, "state").text == "ready", 20, "the page never showed ready")
    browser.find_element(By.ID, "scan").click()
    labels = e2e.scene_labels()
    wait(browser, lambda b: len(rows(b)) == len(labels), 60, "the objects table never filled")
    shown = sorted(r[1] for r in rows(browser))
    assert shown == sorted(labels), shown
    # Figure 21's numbers for each object: centre in cm, opening, orientation.
    for r in rows(browser):
        cx, cy = (float(v) for v in r[3].split(","))
        assert 0 < cx < 100 and 0 < cy < 100, r
        float(r[4]), float(r[5])
    # The annotated scan (Figure 20) is in the view, at the frame's size.
    size = wait(browser, lambda b: b.execute_script(
        "const i = document.getElementById('view'); return i.complete && i.naturalWidth ? [i.naturalWidth, i.naturalHeight] : null"),
        20, "the annotated view never loaded")
    assert size == [640, 480], size
    browser.save_screenshot(str(SHOTS / "1-scan.png"))
    events = [e for e, cmd, _ in log_entries(browser) if cmd == "scan"]
    assert events[0] == "request" and "captured" in events and "detected" in events and events[-1] == "result", events


def test_pick_from_the_page(rig, browser):
    sim, d, _ = rig
    target = "l_shape" if "l_shape" in e2e.scene_labels() else e2e.scene_labels()[0]
    row = next(tr for tr in browser.find_elements(By.CSS_SELECTOR, "#objects tbody tr")
               if tr.find_elements(By.TAG_NAME, "td")[1].text == target)
    row.click()
    assert browser.find_element(By.ID, "pick-name").get_attribute("value") == target
    moves_before = len(sim.moves())
    browser.find_element(By.ID, "pick").click()
    wait(browser, lambda b: any(e == "result" and c == "pick" for e, c, _ in log_entries(b)), 90,
         "the pick's result never reached the log")
    pick = [(e, t) for e, c, t in log_entries(browser) if c == "pick"]
    names = [e for e, _ in pick]
    for needed in ("request", "job_started", "captured", "detected", "identified", "planned", "sent", "step",
                   "step_done", "result"):
        assert needed in names, names
    last_done = len(names) - 1 - names[::-1].index("step_done")
    assert names.index("planned") < last_done < names.index("result"), names
    assert f'"picked":"{target}"' in pick[-1][1], pick[-1][1]
    wait(browser, lambda b: b.find_element(By.ID, "message").text == "pick: done", 20, "the page's pick request never ended")
    browser.save_screenshot(str(SHOTS / "2-pick-done.png"))
    # The firmware executed the plan, and the arm is home (the page's state table says so too).
    assert len(sim.moves()) > moves_before
    st = status(d)
    assert st["job"] is None and st["ready"], st
    assert st["firmware"]["position"] == [0] * 6, st
    assert "ok" in browser.find_element(By.ID, "message").get_attribute("class")


def test_estop_button_while_a_pick_waits(rig, browser):
    sim, d, _ = rig
    target = e2e.scene_labels()[0]
    name = browser.find_element(By.ID, "pick-name")
    name.clear()
    name.send_keys(target)
    base = len(log_entries(browser))
    browser.find_element(By.ID, "pick").click()
    # Wait until the arm carries the part (the page's pick request is still open), then press E-STOP. The wait runs
    # in the page (10 ms polls), so the click follows the carry step's event by little even on a loaded machine.
    browser.set_script_timeout(90)
    browser.execute_async_script("""
        const base = arguments[0], done = arguments[arguments.length - 1];
        const timer = setInterval(() => {
          const lines = [...document.querySelectorAll('#log li')].slice(base);
          if (lines.some((li) => li.dataset.event === 'step' && li.textContent.includes('name="carry"'))) {
            clearInterval(timer);
            done(true);
          }
        }, 10);""", base)
    assert browser.find_element(By.ID, "pick").get_attribute("disabled"), "the pick request is not pending"
    browser.find_element(By.ID, "estop").click()
    wait(browser, lambda b: any(e == "error" and c == "pick" and "estop" in t for e, c, t in log_entries(b)[base:]),
         20, "the pick never ended with the e-stop")
    # The e-stop's own request was answered while the pick's was open; the pick never got home (on a loaded
    # machine the click may land a move or two after carry began, never after the pick's end).
    after = log_entries(browser)[base:]
    assert any(c == "estop" and e == "result" for e, c, _ in after), after
    assert not any(e == "result" and c == "pick" for e, c, _ in after), "the pick completed before the e-stop"
    wait(browser, lambda b: "latched" in b.find_element(By.ID, "message").text, 10, "no e-stop confirmation")
    st1 = status(d)
    time.sleep(0.4)
    st2 = status(d)
    fw = st2["firmware"]
    assert fw["state"] == "FAULT" and "ESTOP_COMMAND" in fw["faults"], fw
    assert st1["firmware"]["position"] == fw["position"], "the arm still moves after the e-stop"
    assert fw["position"] != [0] * 6, "the arm stands at home: the e-stop came after the pick"
    wait(browser, lambda b: b.find_element(By.ID, "state").text == "fault", 10, "the page does not show the fault")
    browser.save_screenshot(str(SHOTS / "3-estop.png"))
    # Clear fault from the page, then home: ready again.
    browser.find_element(By.ID, "clear-fault").click()
    wait(browser, lambda b: any(e == "result" and c == "clear_fault" for e, c, _ in log_entries(b)), 30)
    assert d.request({"cmd": "home"})[1].get("result"), "home after clear_fault failed"
    wait(browser, lambda b: b.find_element(By.ID, "state").text == "ready", 20)


def test_bad_requests_move_nothing(rig):
    sim, d, url = rig
    api = url.rstrip("/") + "/api/"
    before = len(sim.moves())
    pos = status(d)["firmware"]["position"]
    code, body = http(api + "home", "{}")
    assert (code, body["error"]["code"]) == (401, "unauthorized"), body
    assert "token" in body["error"]["message"]
    code, body = http(api + "pick", '{"name":"star","place":"tray"}', token="wrong-token-0123456789")
    assert (code, body["error"]["message"]) == (401, "wrong console token"), body
    for path, payload, want in (("pick", '{"name":', (400, "bad_json")),
                                ("pick", '{"name":"star"}', (400, "missing_field")),
                                ("pick", '{"name":"star","place":"nowhere"}', (409, "unknown_place")),
                                ("home", '{"fast":true}', (400, "bad_field")),
                                ("teleport", "{}", (400, "unknown_command")),
                                ("shutdown", "{}", (403, "not_allowed"))):
        code, body = http(api + path, payload, token=TOKEN)
        assert (code, body["error"]["code"]) == want, (path, payload, body)
        assert body["error"]["message"]
    code, body = http(api + "home", "{}", token=TOKEN, ctype="text/plain")
    assert code == 415, body
    assert len(sim.moves()) == before, "a refused request moved the arm"
    assert status(d)["firmware"]["position"] == pos
    # Reading state on loopback needs no token; the daemon is still up.
    code, body = http(api + "status")
    assert code == 200 and body["result"]["ready"], body


def test_console_config_errors(tmp_path):
    """A console beyond loopback without a token is refused before anything starts, from the file or --console."""
    rbx1d = e2e.need(e2e.BIN / "rbx1d")
    cfg = e2e.absolutize(e2e.load_default_config())
    cfg["console"] = {"bind": "0.0.0.0:8080"}
    r = subprocess.run([rbx1d, "--config", e2e.write_config(tmp_path, cfg), "--check-config"], capture_output=True,
                       text=True, timeout=30)
    assert r.returncode == 2, r
    assert 'console.token: must be set when the console listens beyond loopback (console.bind "0.0.0.0:8080")' \
        in r.stderr, r.stderr
    r = subprocess.run([rbx1d, "--config", e2e.DATA / "rbx1.toml", "--console", "192.168.1.5:80", "--check-config"],
                       capture_output=True, text=True, timeout=30)
    assert r.returncode == 2 and "console.token: must be set" in r.stderr and "--console" in r.stderr, r.stderr
    r = subprocess.run([rbx1d, "--config", e2e.DATA / "rbx1.toml", "--console", "8080", "--check-config"],
                       capture_output=True, text=True, timeout=30)
    assert r.returncode == 2 and '--console: must be "HOST:PORT"' in r.stderr, r.stderr
