"""test_world_console_jobs.py - the console drives a sort in the simulated world (headless Chromium, as
tests/e2e/test_console.py): in the jobs panel a recipe naming an unknown class and one naming an unknown place are
refused with the daemon's message, a good one saved; Clear table cancelled after its first pick; the saved recipe
chosen, Sort answered at once (the job runs on, far longer than an HTTP request waits), the progress shown (phase,
picks, objects left, elapsed, rate), Pause and Resume, the sort's end; the world's state agrees; the history page's tables and both charts drawn (the
canvases not blank); both pages at a phone's 390 px: nothing runs off the screen, the E-STOP on screen and the
first thing under a finger at its centre. Screenshots go to build/e2e/console-jobs/."""
import json
import time
from pathlib import Path

import pytest
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select

import worldkit
from worldkit import e2e
from consolepage import as_phone, chromium, log_entries, reach, wait  # tests/e2e, on the path through worldkit

SHOTS = e2e.ROOT / "build" / "e2e" / "console-jobs"


@pytest.fixture
def cell(tmp_path):
    scene_path = tmp_path / "world.json"
    worldkit.make_world(scene_path, 21, objects=5, errors=(1.0, 0.0, 0.0), classes="rectangle,ellipse,triangle")
    # In real time: a click on the page (Pause after a pick is shown) must land before the next pick ends, also on a
    # loaded machine where the browser lags by seconds.
    c = worldkit.Cell(tmp_path, scene_path, time_scale=1.0)
    yield c
    c.stop()


@pytest.fixture
def browser(tmp_path):
    drv = chromium(tmp_path / "chromium", 1400, 1100)
    SHOTS.mkdir(parents=True, exist_ok=True)
    yield drv
    drv.quit()


def progress(b):
    """The jobs panel's progress: its phase (data-phase) and each row's text."""
    p = b.find_element(By.ID, "job-progress")
    rows = {k: b.find_element(By.ID, "jp-" + k).text for k in ("job", "phase", "picked", "left", "elapsed", "rate")}
    return p.get_attribute("data-phase"), rows


def canvas_drawn(b, cid):
    """Pixels drawn on the canvas (its background is transparent: alpha > 0 is drawn), and its size."""
    return b.execute_script("""
        const c = document.getElementById(arguments[0]);
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let n = 0;
        for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++;
        return [n, c.width, c.height];""", cid)


def shot(b, name):
    """A screenshot with the jobs panel's progress in view."""
    b.execute_script("document.getElementById('job-progress').scrollIntoView({block: 'center'})")
    b.save_screenshot(str(SHOTS / name))


def save_recipe(b, name, recipe):
    """Types recipe into the editor and saves it as name; returns the editor's message once it changed."""
    b.execute_script("document.getElementById('recipe-msg').textContent = ''")
    text, field = b.find_element(By.ID, "recipe-text"), b.find_element(By.ID, "recipe-name")
    text.clear()
    text.send_keys(json.dumps(recipe))
    field.clear()
    field.send_keys(name)
    b.find_element(By.ID, "recipe-save").click()
    return wait(b, lambda d: d.find_element(By.ID, "recipe-msg").text, 20, "no answer to Save recipe")


def test_a_sort_from_the_page_with_pause_and_resume_then_the_history_page(cell, browser):
    url = cell.daemon.console_url()
    browser.get(url)
    wait(browser, lambda b: b.find_element(By.ID, "state").text == "ready", 30, "the page never showed ready")
    wait(browser, lambda b: b.find_element(By.ID, "jobs-panel").is_displayed(), 10, "no jobs panel")
    classes = sorted({o["class"] for o in cell.scene["objects"]})
    recipe = {c: "tray" if i % 2 == 0 else "bin" for i, c in enumerate(classes)}
    # The editor: what the daemon refuses, with its message naming the bad class or place; then a good one saved.
    browser.find_element(By.CSS_SELECTOR, "#recipe-editor summary").click()
    said = save_recipe(browser, "bad", {"bolt": "tray"})
    assert said.startswith("bad_recipe:") and '"bolt"' in said, said
    said = save_recipe(browser, "bad", {classes[0]: "moon"})
    assert said.startswith("bad_recipe:") and '"moon"' in said and classes[0] in said, said
    said = save_recipe(browser, "cell", recipe)
    assert said.startswith('saved "cell" in ') and said.endswith("/recipes.json"), said
    assert json.loads(Path(said.split(" in ", 1)[1]).read_text()) == {"cell": recipe}
    # Clear table, cancelled once it has picked one: it finishes the pick under way (at most one more) and goes home.
    n = len(cell.scene["objects"])
    browser.find_element(By.ID, "clear").click()
    wait(browser, lambda b: b.find_element(By.ID, "message").text.startswith("clear: started (job "), 30,
         "the clear's start was never answered")
    wait(browser, lambda b: progress(b)[1]["picked"].startswith("1 "), 90, "the clear's first pick never shown")
    browser.find_element(By.ID, "job-cancel").click()
    wait(browser, lambda b: progress(b)[0] == "ended", 120, "the cancelled clear never ended")
    summary = browser.find_element(By.ID, "job-summary").text
    cleared = [o for o in cell.world.state()["objects"] if o["place"]]
    # It finishes the pick under way and no more. When the cancel reached the daemon (the log's order is the bus's;
    # the page may show a pick late on a loaded machine), beyond the picks already verified there can be one placed
    # and not yet verified (a pick is judged on the next cycle's scan) and one under way.
    log = log_entries(browser)
    at_cancel = next(i for i, (_, cmd, _) in enumerate(log) if cmd == "cancel")
    verified = sum(1 for event, cmd, _ in log[:at_cancel] if cmd == "clear" and event == "pick_verified")
    assert 1 <= len(cleared) <= verified + 2, (verified, cleared)
    assert all(o["place"] == "bin" for o in cleared), cleared
    assert "clear (job 1) cancelled: picked %d" % len(cleared) in summary, summary
    # The chooser lists the saved recipes; the one just saved is chosen.
    choice = Select(browser.find_element(By.ID, "recipe-choice"))
    wait(browser, lambda b: [o.text for o in choice.options] == ["(as edited below)", "cell"], 10,
         "the chooser does not list the saved recipe")
    assert choice.first_selected_option.text == "cell"
    browser.find_element(By.ID, "sort").click()
    # Answered as soon as the sort started; its progress follows on the event stream.
    wait(browser, lambda b: b.find_element(By.ID, "message").text.startswith("sort: started (job "), 30,
         "the sort's start was never answered")
    assert progress(browser)[0] != "ended", progress(browser)
    assert browser.find_element(By.ID, "sort").get_attribute("disabled"), "Sort stays enabled while a sort runs"
    wait(browser, lambda b: progress(b)[0] == "pick", 60, "no pick in progress shown")
    phase, rows = progress(browser)
    assert rows["left"] != "–" and int(rows["left"]) >= 1 and rows["rate"].endswith("picks/min"), rows
    assert rows["elapsed"].endswith(" s") and rows["picked"].endswith("attempts)"), rows
    shot(browser, "0-sort-running.png")
    browser.find_element(By.ID, "job-pause").click()
    wait(browser, lambda b: progress(b)[0] == "paused", 60, "the pause was never shown")
    wait(browser, lambda b: not b.find_element(By.ID, "job-resume").get_attribute("disabled"), 5, "Resume disabled")
    assert browser.find_element(By.ID, "job-pause").get_attribute("disabled"), "Pause enabled while paused"
    elapsed = progress(browser)[1]["elapsed"]
    wait(browser, lambda b: progress(b)[1]["elapsed"] != elapsed, 5, "the elapsed time stands still while paused")
    shot(browser, "1-sort-paused.png")
    browser.find_element(By.ID, "job-resume").click()
    wait(browser, lambda b: progress(b)[0] == "ended", 180, "the sort never ended")
    summary = browser.find_element(By.ID, "job-summary").text
    phase, rows = progress(browser)
    shot(browser, "2-sort-done.png")
    rest = n - len(cleared)
    assert "sort (job 2) done: picked %d" % rest in summary, summary
    assert rows["phase"] == "done" and rows["left"] == "0" and rows["picked"].startswith(str(rest)), rows
    assert not browser.find_element(By.ID, "sort").get_attribute("disabled"), "Sort disabled after the sort"
    state = cell.world.state()
    assert all(o["place"] == ("bin" if o in cleared else recipe[o["class"]]) for o in state["objects"]), state["objects"]
    assert state["counts"]["collisions"] == 0

    browser.find_element(By.ID, "history-link").click()
    wait(browser, lambda b: len(b.find_elements(By.CSS_SELECTOR, "#picks tbody tr")) == n, 30, "no picks in the table")
    jobs = [[td.text for td in tr.find_elements(By.TAG_NAME, "td")]
            for tr in browser.find_elements(By.CSS_SELECTOR, "#jobs tbody tr")]
    assert [j[1] for j in jobs] == ["sort", "clear"] and [j[5] for j in jobs] == ["done", "cancelled"], jobs
    assert jobs[0][2] == '"cell"' and [j[6] for j in jobs] == [str(rest), str(len(cleared))], jobs
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

    # A phone at the arm: both pages in one column, the E-STOP on screen and under the finger at every scroll.
    as_phone(browser)
    time.sleep(0.5)  # the charts redraw at the new size
    for page in ("history", "console"):
        if page == "console":
            browser.get(url)
            wait(browser, lambda b: b.find_element(By.ID, "state").text == "ready", 30, "the page never showed ready")
            wait(browser, lambda b: progress(b)[0] == "ended", 30, "the last sort is not shown")
        layout = reach(browser)
        assert layout["overflow_px"] <= 0, (page, layout)
        assert all(p["estop_in"] and p["estop_hit"] and p["token_hit"] is not False for p in layout["positions"]), \
            (page, layout)
        browser.save_screenshot(str(SHOTS / ("4-history-phone.png" if page == "history" else "5-console-phone.png")))
