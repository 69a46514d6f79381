"""test_link_faults.py - corrupt and dropped bytes, a 2 s outage and a vanished-and-returned port during a pick:
the firmware's executed entries are exactly the plan (none lost, none repeated) and the pick completes."""
import threading
import time

import rbx1e2e as e2e
from lineproxy import LineProxy


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
    proxy = LineProxy(sim.port, str(tmp_path / "rbx1-port"))
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


def two_second_outage(proxy):
    time.sleep(0.05)
    proxy.set_cut(True)
    time.sleep(2.0)
    proxy.set_cut(False)


def test_two_second_outage(tmp_path, sim, daemon_factory):
    events, final = run_with_outage(tmp_path, sim, daemon_factory, "descend", two_second_outage)
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


def test_lost_move_responses_and_a_lost_hello_are_no_false_reset(sim, daemon_factory):
    """A MOVE executed whose six answers were lost, then a HELLO of the reconnection executed and unanswered too:
    HELLO's last_seq names that HELLO, not the MOVE. The journal reads STATUS.moves_accepted instead: the move is
    known to be queued, never sent again, and no 'moves_done jumped' ends the pick as a false firmware_reset."""
    d = daemon_factory(sim.port)
    sim.control("drop 4 6")  # MOVE: the first one of the pick (to the scan pose) runs, its answers are lost
    sim.control("drop 1 6")  # HELLO: the first one of the reconnection likewise
    events, final = pick(d, e2e.scene_labels()[0])
    assert "result" in final, final
    journal = e2e.events_named(events, "journal")
    assert journal and journal[0]["accepted_before_outage"] is True, journal
    log = sim.moves()
    scan = [e for e in events if e["event"] == "step_done"][0]
    assert log[0]["target"] == scan["target"]
    e2e.assert_log_is_plan(log[1:], e2e.planned_waypoints(events))


def test_link_error_on_clear_fault_after_heartbeat_loss(tmp_path, sim, daemon_factory):
    """A 2 s outage loses the heartbeat; the CLEAR_FAULT that follows is executed but its answers are lost (a link
    error): the job recovers the link, reads that the fault is gone, and completes the pick."""
    sim.control("drop 9 6")

    events, final = run_with_outage(tmp_path, sim, daemon_factory, "descend", two_second_outage)
    assert e2e.events_named(events, "heartbeat_lost"), [e["event"] for e in events]
    assert final["result"]["link_recoveries"] >= 2, final  # the outage, then the CLEAR_FAULT
    downs = [e for e in events if e["event"] == "link_down"]
    assert len(downs) >= 2, [e["event"] for e in events]
