"""consolepage.py - reading the web console's page in the browser tests (test_console, test_newuser): waits on DOM
conditions, the numbered event log, the arm's status rows."""
from selenium.common.exceptions import TimeoutException, WebDriverException
from selenium.webdriver.support.ui import WebDriverWait


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
