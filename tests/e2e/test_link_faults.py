"""test_link_faults.py - corrupt and dropped bytes, a 2 s outage and a vanished-and-returned port during a pick:
the firmware's executed entries are exactly the plan (none lost, none repeated) and the pick completes."""
import threading
import time

import rbx1e2e as e2e
from ptyproxy import PtyProxy


def pick(d, name, on_event=None):
    return d.request({"cmd": "pick", "name": name, "place": "tray"}, timeout=180, on_event=on_event)


def pick_log(sim):
    """The move log minus the move to the scan pose (the first entry)."""
    return sim.moves()[1:]


def test_corrupt_and_dropped_bytes(tmp_path, daemon_factory):
    sim = e2e.Simfw(tmp_path, "--eeprom", tmp_path / "eeprom.bin", "--corrupt", "0.003", "--drop", "0.003",
                    "--seed", "7")
    try:
        e2e.configure_fast_firmware_retrying(sim.port)
        d = daemon_factory(sim.port)
        name = e2e.scene_labels()[0]
        events, final = pick(d, name)
        assert "result" in final, final
        e2e.assert_log_is_plan(pick_log(sim), e2e.planned_waypoints(events))
        _, st = d.request({"cmd": "status"})
        assert st["result"]["link"]["retransmissions"] > 0, "no fault was injected"
    finally:
        sim.stop()


def run_with_outage(tmp_path, sim, daemon_factory, step, outage):
    proxy = PtyProxy(sim.port, str(tmp_path / "rbx1-port"))
    try:
        d = daemon_factory(proxy.link_path)
        name = e2e.scene_labels()[0]
        done = threading.Event()

        def on_event(ev):
            if ev["event"] == "step" and ev["name"] == step and not done.is_set():
                done.set()
                threading.Thread(target=outage, args=(proxy,), daemon=True).start()

        events, final = pick(d, name, on_event)
        assert done.is_set(), f"the pick never reached {step}"
        assert "result" in final, final
        names = [e["event"] for e in events]
        assert "link_down" in names and "link_up" in names, names
        e2e.assert_log_is_plan(pick_log(sim), e2e.planned_waypoints(events))
        return events, final
    finally:
        proxy.close()


def test_two_second_outage(tmp_path, sim, daemon_factory):
    def outage(proxy):
        time.sleep(0.05)
        proxy.set_cut(True)
        time.sleep(2.0)
        proxy.set_cut(False)

    events, final = run_with_outage(tmp_path, sim, daemon_factory, "descend", outage)
    # 2 s outlive the firmware's 1 s heartbeat: it stopped; the flushed entries were sent again, once.
    assert e2e.events_named(events, "heartbeat_lost"), [e["event"] for e in events]


def test_vanished_and_returned_port(tmp_path, sim, daemon_factory):
    def outage(proxy):
        time.sleep(0.05)
        proxy.vanish()
        time.sleep(2.0)
        proxy.reappear()

    events, final = run_with_outage(tmp_path, sim, daemon_factory, "carry", outage)
    assert final["result"]["link_recoveries"] >= 1


def test_firmware_reset_mid_pick_is_never_guessed(sim, daemon_factory):
    """A power-cycled board (simfw `reset`) forgot where the arm is: the job fails with firmware_reset, the daemon
    stops being ready, and only the operator's clear_fault declares the positions again."""
    d = daemon_factory(sim.port)
    fired = threading.Event()

    def on_event(ev):
        if ev["event"] == "step" and ev["name"] == "lift" and not fired.is_set():
            fired.set()
            sim.control("reset")

    events, final = pick(d, e2e.scene_labels()[0], on_event)
    assert fired.is_set()
    assert final["error"]["code"] == "firmware_reset", final
    deadline = time.monotonic() + 5
    while d.request({"cmd": "status"})[1]["result"]["ready"]:
        assert time.monotonic() < deadline, "still ready after the reset"
        time.sleep(0.1)
    _, final = d.request({"cmd": "home"})
    assert final["error"]["code"] == "not_ready" and "clear-fault" in final["error"]["message"], final
    n = len(sim.moves())
    _, final = d.request({"cmd": "clear_fault"})
    assert "result" in final, final
    _, final = d.request({"cmd": "home"})
    assert "result" in final, final
    assert len(sim.moves()) == n + 1  # only the home move ran after the reset
