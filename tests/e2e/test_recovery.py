"""test_recovery.py - what the daemon believes after a crash or a power cycle (issue 8, defects 1 and 2).

A daemon killed mid-pick and started again at once (within the firmware's heartbeat) finds the dead daemon's
entries still queued: it stops them before it is ready and never counts them as its own. A firmware that comes back
from a power cycle on the same device name (a fresh rbx1-simfw on the same --link path) has lost its positions:
the daemon is not ready until `clear_fault`, whether it was idle or a job was running."""
import os
import threading
import time

import pytest

import rbx1e2e as e2e
from conftest import fast_config


def set_heartbeat(port, ms):
    """A long firmware heartbeat, so that 'restarted within the heartbeat' holds however loaded the machine is."""
    from rbx1proto.link import Link
    from rbx1proto.messages import GLOBAL_JOINT, Key, MsgType
    with Link(port) as link:
        link.hello()
        r = link.request(MsgType.CONFIG_SET, joint=GLOBAL_JOINT, key=Key.HEARTBEAT_MS, value=ms)
        assert r["status"] == 0, r


def pick(d, name, on_event=None):
    return d.request({"cmd": "pick", "name": name, "place": "tray"}, timeout=180, on_event=on_event)



def test_restarted_daemon_stops_the_dead_daemons_queue(tmp_path, sim, daemon_factory):
    set_heartbeat(sim.port, 30000)
    # The dead daemon's arm moves slowly, so that its queued entries outlast a slow restart of the next daemon.
    slow = fast_config()
    slow["arm"]["speeds"]["joint_speed_deg_s"] = e2e.FAST_DEG_S / 6
    d1 = daemon_factory(sim.port, slow)
    old_events = []
    killed = threading.Event()

    def on_event(ev):
        old_events.append(ev)
        if ev["event"] == "step" and ev["name"] == "approach" and not killed.is_set():
            d1.proc.kill()  # kill -9 while the approach runs and the rest of the pick waits in the queue
            killed.set()

    try:
        pick(d1, e2e.scene_labels()[0], on_event)
    except (AssertionError, OSError):
        pass  # the connection died with the daemon
    assert killed.wait(60), "the pick never reached its approach"
    d1.proc.wait()
    old_plan = e2e.planned_waypoints(old_events)
    os.unlink(d1.socket)  # the dead daemon's socket file
    (tmp_path / "second").mkdir()
    d2 = e2e.Daemon(tmp_path / "second", fast_config(), sim.port)
    try:
        at_ready = len(sim.moves())
        done_old = at_ready - 1  # the first entry was the old pick's move to the scan pose
        assert done_old < len(old_plan), "the old pick had finished before the restart: nothing was exercised"
        events, final = pick(d2, e2e.scene_labels()[0])
        assert "result" in final, final
        # Everything that completed after the new daemon was ready is its own: its scan move, then its plan.
        after = sim.moves()[at_ready:]
        scan = [e for e in events if e["event"] == "step_done"][0]
        assert after[0]["kind"] == "move" and after[0]["target"] == scan["target"], (after[0], scan)
        e2e.assert_log_is_plan(after[1:], e2e.planned_waypoints(events))
        assert "this host did not send; stopping them" in d2.log_path.read_text()
        # The old entries that had not completed never ran: the first entry after the old ones is the new scan.
        assert [m["target"] for m in sim.moves()[1:at_ready]] == [w["target"] for w in old_plan[:done_old]]
    finally:
        d2.stop()


def power_cycle(tmp_path, sim, link, off_s):
    """Kill the simulated board (kill -9: no goodbye), its device name gone, and a fresh one back after off_s."""
    sim.proc.kill()
    sim.proc.wait()
    if os.path.lexists(link):
        os.unlink(link)  # as a USB device vanishes; also keeps the dead pty's name from being reused under us
    time.sleep(off_s)
    return e2e.Simfw(tmp_path, "--eeprom", tmp_path / "eeprom.bin", "--link", link)


def assert_held_until_clear_fault(d, sim2):
    """Connected to the fresh firmware and not ready, saying why; home refused; clear_fault, then home moves."""
    deadline = time.monotonic() + 20
    while True:
        st = e2e.status(d, timeout=10)
        if st["link"]["connected"] and st["firmware"] and "clear-fault" in st["link"].get("error", ""):
            break
        assert not st["ready"], f"ready again after the power cycle: {st}"
        assert time.monotonic() < deadline, f"never reconnected to the fresh firmware: {st}"
        time.sleep(0.1)
    time.sleep(1.0)  # and it stays so
    st = e2e.status(d, timeout=10)
    assert not st["ready"], st
    assert d.log_path.read_text().count("positions declared") == 1, "declared again without the operator"
    _, final = d.request({"cmd": "home"})
    assert final["error"]["code"] == "not_ready" and "clear-fault" in final["error"]["message"], final
    assert sim2.moves() == []
    _, final = d.request({"cmd": "clear_fault"})
    assert "result" in final, final
    _, final = d.request({"cmd": "home"})
    assert "result" in final, final
    assert len(sim2.moves()) == 1


# 2 s: inside the daemon's link timings (boot_wait 2.5 s); 6 s: past every idle-path timer of the daemon (the
# issue's 35 s only added reconnect_timeout_s = 30 s, which an idle daemon never uses; the job-running test below
# covers a power cycle that outlives it).
@pytest.mark.parametrize("off_s", [2.0, 6.0])
def test_power_cycle_while_idle_holds(tmp_path, daemon_factory, off_s):
    link = str(tmp_path / "rbx1-port")
    sim = e2e.Simfw(tmp_path, "--eeprom", tmp_path / "eeprom.bin", "--link", link)
    e2e.configure_fast_firmware(sim.port)
    d = daemon_factory(link)
    sim2 = power_cycle(tmp_path, sim, link, off_s)
    try:
        assert_held_until_clear_fault(d, sim2)
    finally:
        sim2.stop()


def test_power_cycle_during_a_pick_past_the_reconnect_timeout_holds(tmp_path, daemon_factory):
    link = str(tmp_path / "rbx1-port")
    sim = e2e.Simfw(tmp_path, "--eeprom", tmp_path / "eeprom.bin", "--link", link)
    e2e.configure_fast_firmware(sim.port)
    cfg = fast_config()
    cfg["daemon"]["reconnect_timeout_s"] = 1.0
    d = daemon_factory(link, cfg)
    box = {}

    def on_event(ev):
        if ev["event"] == "step" and ev["name"] == "lift" and "sim2" not in box:
            box["sim2"] = None
            threading.Thread(target=lambda: box.update(sim2=power_cycle(tmp_path, sim, link, 2.5)),
                             daemon=True).start()

    events, final = pick(d, e2e.scene_labels()[0], on_event)
    deadline = time.monotonic() + 10
    while box.get("sim2") is None:
        assert time.monotonic() < deadline
        time.sleep(0.05)
    try:
        assert final["error"]["code"] == "link_down", final
        assert_held_until_clear_fault(d, box["sim2"])
    finally:
        box["sim2"].stop()
