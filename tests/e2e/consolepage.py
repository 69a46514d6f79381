"""consolepage.py - the web console's page in the browser tests (test_console, test_newuser, tests/world): a headless
Chromium, waits on DOM conditions, the numbered event log, the arm's status rows, the layout on a phone."""
from selenium import webdriver
from selenium.common.exceptions import TimeoutException, WebDriverException
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.support.ui import WebDriverWait

import rbx1e2e as e2e


def chromium(user_dir, width=1400, height=1100):
    """Headless Chromium (Debian's chromium-driver) with a window of width x height CSS pixels. No GPU here: the
    console's 3D view runs WebGL on Chromium's software renderer (SwiftShader), which newer Chromiums want asked for."""
    opts = webdriver.ChromeOptions()
    opts.binary_location = e2e.need("/usr/bin/chromium")
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-dev-shm-usage",
              f"--window-size={width},{height}", "--user-data-dir=" + str(user_dir)):
        opts.add_argument(a)
    drv = webdriver.Chrome(service=Service(e2e.need("/usr/bin/chromedriver")), options=opts)
    drv.set_page_load_timeout(20)
    return drv


def as_phone(drv, width=390, height=844):
    """The tab as a phone's screen: a width x height CSS-pixel viewport, mobile (the page's viewport meta applies,
    scrollbars overlay), whatever the window's size."""
    drv.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                        {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": True})


def wait(drv, what, timeout=60, msg=""):
    """what(drv) once it is truthy; on timeout the error also carries what the page said and its last log lines."""
    try:
        return WebDriverWait(drv, timeout, poll_frequency=0.05).until(lambda d: what(d))
    except TimeoutException:
        raise TimeoutException(f"{msg} (after {timeout} s; {page_context(drv)})") from None


def page_context(drv):
    try:
        said = drv.execute_script("const m = document.getElementById('message'); return m ? m.textContent : null")
        return f"page message {said!r}, last log lines {log_entries(drv)[-8:]}"
    except WebDriverException as e:  # the tab is gone
        return f"page unreadable: {e.msg}"


def log_entries(drv, after=0):
    """The event log's lines numbered above after, as (event, cmd, text) (the page keeps the last 500 lines)."""
    return drv.execute_script(
        "return [...document.querySelectorAll('#log li')].filter(li => li.value > arguments[0])"
        ".map(li => [li.dataset.event, li.dataset.cmd, li.textContent])", after)


def last_seq(drv):
    return drv.execute_script("const l = document.querySelector('#log li:last-child'); return l ? l.value : 0")


def status_row(drv, key):
    """The text of the arm table's row named key (None when absent)."""
    return drv.execute_script("""
        const row = [...document.querySelectorAll('#arm-state tr')].find(tr => tr.cells[0].textContent === arguments[0]);
        return row ? row.cells[1].textContent : null;""", key)


def reach(drv):
    """The page's layout on a small screen, scrolled to its top, middle and bottom: whether anything runs off to the
    right (the document wider than the window), and at each scroll position whether the E-STOP is inside the window
    and is what a finger at its centre touches (elementFromPoint), and the same for the token field when on screen.
    Returns {"width", "overflow_px", "positions": [{"scroll", "estop_in", "estop_hit", "token_hit"}]}."""
    return drv.execute_script("""
        const doc = document.documentElement;
        const hit = (el) => {
          const r = el.getBoundingClientRect();
          const inside = r.width > 0 && r.left >= 0 && r.top >= 0 && r.right <= innerWidth && r.bottom <= innerHeight;
          const at = inside ? document.elementFromPoint((r.left + r.right) / 2, (r.top + r.bottom) / 2) : null;
          return {inside, hit: !!at && (at === el || el.contains(at))};
        };
        const out = {width: innerWidth, overflow_px: Math.max(doc.scrollWidth, document.body.scrollWidth) - innerWidth,
                     positions: []};
        const bottom = doc.scrollHeight - innerHeight;
        for (const y of [0, Math.round(bottom / 2), bottom]) {
          scrollTo(0, y);
          const e = hit(document.getElementById('estop')), t = hit(document.getElementById('token'));
          out.positions.push({scroll: scrollY, estop_in: e.inside, estop_hit: e.hit,
                              token_hit: t.inside ? t.hit : null});
        }
        scrollTo(0, 0);
        return out;""")
