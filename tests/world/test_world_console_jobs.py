"""test_world_console_jobs.py - the console drives a sort in the simulated world (headless Chromium, as
tests/e2e/test_console.py): the recipe typed in the jobs panel, Sort, the progress shown, Pause and Resume, the sort's
end; the world's state agrees; the history page's tables and both charts drawn (the canvases not blank); the page
at a phone's 390 px: one column, the E-STOP clear of the token field and inside the screen. Screenshots go to
build/e2e/console-jobs/."""
import json

import pytest
from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By

import worldkit
from worldkit import e2e
from consolepage import wait  # tests/e2e, on the path through worldkit

SHOTS = e2e.ROOT / "build" / "e2e" / "console-jobs"


@pytest.fixture
def cell(tmp_path):
    scene_path = tmp_path / "world.json"
    worldkit.make_world(scene_path, 21, objects=3, errors=(1.0, 0.0, 0.0), classes="rectangle,ellipse,triangle")
    c = worldkit.Cell(tmp_path, scene_path)
    yield c
    c.stop()


@pytest.fixture
def browser(tmp_path):
    opts = webdriver.ChromeOptions()
    opts.binary_location = e2e.need("/usr/bin/chromium")
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
              "--window-size=1400,1100", "--user-data-dir=" + str(tmp_path / "chromium")):
        opts.add_argument(a)
    drv = webdriver.Chrome(service=Service(e2e.need("/usr/bin/chromedriver")), options=opts)
    drv.set_page_load_timeout(20)
    SHOTS.mkdir(parents=True, exist_ok=True)
    yield drv
    drv.quit()


def progress(b):
    p = b.find_element(By.ID, "job-progress")
    return p.get_attribute("data-phase"), p.text


def canvas_drawn(b, cid):
    """Pixels drawn on the canvas (not all transparent), and its size."""
    return b.execute_script("""
        const c = document.getElementById(arguments[0]);
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let n = 0;
        for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++;
        return [n, c.width, c.height];""", cid)


def test_a_sort_from_the_page_with_pause_and_resume_then_the_history_page(cell, browser):
    url = cell.daemon.console_url()
    browser.get(url)
    wait(browser, lambda b: b.find_element(By.ID, "state").text == "ready", 30, "the page never showed ready")
    wait(browser, lambda b: b.find_element(By.ID, "jobs-panel").is_displayed(), 10, "no jobs panel")
    classes = sorted({o["class"] for o in cell.scene["objects"]})
    recipe = {c: "tray" if i % 2 == 0 else "bin" for i, c in enumerate(classes)}
    field = browser.find_element(By.ID, "sort-recipe")
    field.clear()
    field.send_keys(json.dumps(recipe))
    browser.find_element(By.ID, "sort").click()
    wait(browser, lambda b: progress(b)[0] == "pick", 60, "no pick in progress shown")
    browser.save_screenshot(str(SHOTS / "0-sort-running.png"))
    browser.find_element(By.ID, "job-pause").click()
    wait(browser, lambda b: progress(b)[0] == "paused", 60, "the pause was never shown")
    paused = progress(browser)[1]
    browser.save_screenshot(str(SHOTS / "1-sort-paused.png"))
    browser.find_element(By.ID, "job-resume").click()
    wait(browser, lambda b: progress(b)[0] == "ended", 120, "the sort never ended")
    text = progress(browser)[1]
    browser.save_screenshot(str(SHOTS / "2-sort-done.png"))
    n = len(cell.scene["objects"])
    assert "done: picked %d" % n in text, (paused, text)
    state = cell.world.state()
    assert all(o["place"] == recipe[o["class"]] for o in state["objects"]), state["objects"]
    assert state["counts"]["collisions"] == 0

    browser.find_element(By.ID, "history-link").click()
    wait(browser, lambda b: len(b.find_elements(By.CSS_SELECTOR, "#picks tbody tr")) == n, 30, "no picks in the table")
    jobs = [td.text for td in browser.find_elements(By.CSS_SELECTOR, "#jobs tbody tr td")]
    assert jobs[1] == "sort" and jobs[5] == "done" and jobs[6] == str(n), jobs
    for cid in ("chart-classes", "chart-cycle"):
        drawn = wait(browser, lambda b: canvas_drawn(b, cid)[0] > 500 and canvas_drawn(b, cid), 20, cid + " is blank")
        assert drawn[1] > 200 and drawn[2] > 100, (cid, drawn)
    # A pick's scan on click: the JPEG the history kept.
    browser.find_element(By.CSS_SELECTOR, "#picks tbody tr").click()
    size = wait(browser, lambda b: b.execute_script(
        "const i = document.getElementById('scan-image'); return i.complete && i.naturalWidth ? [i.naturalWidth, i.naturalHeight] : null"),
        20, "the pick's scan never loaded")
    assert size == [800, 600], size
    browser.save_screenshot(str(SHOTS / "3-history.png"))

    # A phone at the arm: one column, the E-STOP on screen and clear of the token field.
    browser.set_window_size(390, 844)
    browser.save_screenshot(str(SHOTS / "4-history-phone.png"))
    browser.get(url)
    wait(browser, lambda b: b.find_element(By.ID, "state").text == "ready", 30, "the page never showed ready")
    geo = browser.execute_script("""
        const r = (id) => document.getElementById(id).getBoundingClientRect();
        const e = r('estop'), t = r('token'), s = r('side'), v = r('view-panel');
        const overlap = !(e.right <= t.left || t.right <= e.left || e.bottom <= t.top || t.bottom <= e.top);
        return {overlap, estop_in: e.left >= 0 && e.right <= innerWidth && e.top >= 0 && e.bottom <= innerHeight,
                side_in: s.right <= innerWidth + 1, stacked: s.top >= v.bottom, width: innerWidth};""")
    browser.save_screenshot(str(SHOTS / "5-console-phone.png"))
    assert geo["estop_in"] and not geo["overlap"] and geo["side_in"] and geo["stacked"], geo
