"""test_job_limits.py - what the daemon promises when a job cannot finish: move_timeout_s, job_timeout_s and
reconnect_timeout_s fail the job with their error code after their time (not before), and shutdown while the arm
moves ends in a controlled STOP: the arm stands still, short of the interrupted move's target, with no fault."""
import signal
import threading
import time

import rbx1e2e as e2e
from conftest import fast_config
from lineproxy import LineProxy

IDLE, STOPPING = 0, 3
HEARTBEAT_LOST = 1 << 3


def firmware_status(port):
    """STATUS straight from the firmware (no daemon on the port)."""
    from rbx1proto.link import Link
    from rbx1proto.messages import MsgType
    with Link(port) as link:
        link.hello()
        return link.request(MsgType.STATUS)


def slow_firmware(port, steps_per_s):
    """Lowers every joint's MAX_SPEED: moves then take longer than the daemon's plan at FAST_DEG_S."""
    from rbx1proto.link import Link
    from rbx1proto.messages import Key, MsgType
    with Link(port) as link:
        link.hello()
        for j in range(6):
            assert link.request(MsgType.CONFIG_SET, joint=j, key=Key.MAX_SPEED, value=steps_per_s)["status"] == 0


def wait_still(d, timeout=10):
    """Polls the daemon's view of the firmware until the arm is at rest (not MOVING or STOPPING); returns it."""
    deadline = time.monotonic() + timeout
    while True:
        _, st = d.request({"cmd": "status"}, timeout=10)
        fw = st["result"]["firmware"]
        if fw["state"] not in ("MOVING", "STOPPING"):
            return fw
        assert time.monotonic() < deadline, f"the arm still moves {timeout} s after the job failed: {fw}"
        time.sleep(0.1)


def timed(d, req):
    t0 = time.monotonic()
    events, final = d.request(req, timeout=60)
    return events, final, time.monotonic() - t0


def test_move_timeout_fails_the_job_and_stops_the_arm(sim, daemon_factory):
    slow_firmware(sim.port, 1500)  # the scan pose move takes seconds instead of its planned fraction of one
    cfg = fast_config()
    cfg["daemon"]["move_timeout_s"] = 0.3
    for j in range(1, 7):  # the config's limits within the board's (else not ready); joint moves keep FAST_DEG_S
        cfg["arm"]["joints"][f"j{j}"]["max_speed_steps_s"] = 1500
    d = daemon_factory(sim.port, cfg)
    events, final, took = timed(d, {"cmd": "scan"})
    assert final["error"]["code"] == "timeout", final
    assert "scan_pose" in final["error"]["message"], final
    sent = e2e.events_named(events, "sent")
    planned_s = sent[0]["duration_ms"] / 1000
    assert took >= planned_s + 0.3, (took, planned_s)
    assert not sim.moves(), "the scan pose move completed: the firmware was not slow enough to show the timeout"
    wait_still(d)
    # Stopped, not left to run on: the move never completed (unstopped, it ends within seconds at this speed).
    assert not sim.moves(), "the timed-out move ran on to its end"


def test_job_timeout_fails_the_job_and_stops_the_arm(sim, daemon_factory):
    cfg = fast_config()
    # The bundled arm speed: the pick's motion dwarfs its computing, so the timeout falls while entries are queued
    # however loaded the machine (at the test speed a loaded run had run every sent entry before it). At 9 s an
    # unloaded run had 29 of 44 sent entries done: past the scan, well short of the whole pick.
    cfg["arm"]["speeds"]["joint_speed_deg_s"] = 20.0
    cfg["daemon"]["job_timeout_s"] = 9.0
    d = daemon_factory(sim.port, cfg)
    events, final, took = timed(d, {"cmd": "pick", "name": e2e.scene_labels()[0], "place": "tray"})
    assert final["error"]["code"] == "timeout", final
    assert 9.0 <= took < 15, took
    wait_still(d)
    # Whatever was queued when the job gave up did not run on: fewer entries completed than the pick queued
    # (unstopped, every queued entry runs to its end before the arm comes to rest).
    queued = len(e2e.events_named(events, "sent"))
    assert e2e.events_named(events, "planned"), "the timeout came before the plan: nothing queued to stop"
    assert len(sim.moves()) < queued, (len(sim.moves()), queued)


def test_reconnect_timeout_fails_the_job(tmp_path, sim, daemon_factory):
    proxy = LineProxy(sim.port, str(tmp_path / "rbx1-port"))
    try:
        cfg = fast_config()
        cfg["daemon"]["reconnect_timeout_s"] = 0.5
        d = daemon_factory(proxy.link_path, cfg)
        gone = {}

        def on_event(ev):
            if ev["event"] == "step" and ev["name"] == "scan_pose" and "t" not in gone:
                gone["t"] = time.monotonic()
                proxy.vanish()

        events, final = d.request({"cmd": "scan"}, timeout=60, on_event=on_event)
        took = time.monotonic() - gone["t"]
        assert final["error"]["code"] == "link_down", final
        assert "0.5" in final["error"]["message"], final
        assert e2e.events_named(events, "link_down"), [e["event"] for e in events]
        assert 0.5 <= took < 5, took
    finally:
        proxy.close()


def test_shutdown_while_moving_is_a_controlled_stop(sim, daemon_factory):
    d = daemon_factory(sim.port)
    out = {}
    seen = []
    fired = threading.Event()

    def on_event(ev):
        seen.append(ev)
        if ev["event"] == "step" and ev["name"] == "carry" and not fired.is_set():
            fired.set()
            d.proc.send_signal(signal.SIGTERM)

    def run():
        try:
            out["events"], out["final"] = d.request({"cmd": "pick", "name": e2e.scene_labels()[0], "place": "tray"},
                                                    on_event=on_event)
        except AssertionError as e:  # the daemon may close the connection before the final line
            out["closed"] = str(e)

    t = threading.Thread(target=run)
    t.start()
    t.join(timeout=120)
    assert fired.is_set(), "the pick never reached the carry step"
    assert d.proc.wait(timeout=10) == 0
    # Read the firmware at once, well inside its 1 s heartbeat: a daemon that left the arm running would show
    # MOVING here (and HEARTBEAT_LOST later), not a stopped, fault-free arm.
    a = firmware_status(sim.port)
    assert a["state"] in (IDLE, STOPPING), dict(a)  # a loaded machine may catch the last of the deceleration
    b = a
    deadline = time.monotonic() + 10  # a starved simulator's clock lags the wall clock: wait for rest, do not guess
    while b["state"] == STOPPING and time.monotonic() < deadline:
        time.sleep(0.05)
        b = firmware_status(sim.port)
    time.sleep(0.3)
    c = firmware_status(sim.port)
    assert b["state"] == IDLE and c["state"] == IDLE, (dict(b), dict(c))
    assert not c["faults"] & HEARTBEAT_LOST, dict(c)  # stopped by the daemon, not by the firmware's heartbeat
    assert b["position"] == c["position"], "the arm still moved after shutdown"
    log = sim.moves()
    assert len(log) == c["moves_done"]
    carry = next(w for w in e2e.planned_waypoints(seen) if w["name"] == "carry")
    assert all(e["target"] != carry["target"] for e in log if e["kind"] == "move"), "carry completed"
    assert list(c["position"]) != list(carry["target"])
    if "final" in out:  # the final line, when it got out before the socket closed, names the reason
        assert out["final"]["error"]["code"] == "shutdown", out["final"]
