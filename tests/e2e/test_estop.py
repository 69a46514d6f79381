"""test_estop.py - an e-stop mid-move (the control request, and the simulated e-stop input) stops the motion at
once, aborts the job with an estop event and error, and latches until clear_fault."""
import threading
import time

import rbx1e2e as e2e


def start_pick(d, name, trigger_step, on_trigger):
    """Runs a pick in a thread; calls on_trigger once the named step is executing."""
    out = {}
    fired = threading.Event()

    def on_event(ev):
        if ev["event"] == "step" and ev["name"] == trigger_step and not fired.is_set():
            fired.set()
            threading.Thread(target=on_trigger, daemon=True).start()

    def run():
        out["events"], out["final"] = d.request({"cmd": "pick", "name": name, "place": "tray"}, on_event=on_event)

    t = threading.Thread(target=run)
    t.start()
    return t, out, fired


def assert_stopped(d, sim, fault):
    _, st1 = d.request({"cmd": "status"})
    time.sleep(0.4)
    _, st2 = d.request({"cmd": "status"})
    fw1, fw2 = st1["result"]["firmware"], st2["result"]["firmware"]
    assert fw2["state"] == "FAULT", fw2
    assert fault in fw2["faults"], fw2
    assert fw1["position"] == fw2["position"], "the arm still moves after the e-stop"
    return fw2


def assert_interrupted(events, sim, fw, step):
    """The move that was executing never completed: the firmware's log of completed entries is the plan's prefix
    (and counts exactly moves_done entries), the first entry missing from it is one of the phase `step` (a straight
    line is several moves of one name), and the arm stands short of that entry's target."""
    planned = e2e.planned_waypoints(events)
    log = sim.moves()
    assert len(log) == fw["moves_done"], (len(log), fw)
    # The entries before it (and the scan pose move) did complete: the log is the plan's prefix.
    done = [(e["kind"], e["target"] if e["kind"] == "move" else e.get("pulse_us")) for e in log[1:]]
    index = len(done)
    want = [(w["kind"], w["target"] if w["kind"] == "move" else w["pulse_us"]) for w in planned[:index]]
    assert done == want, (done, want)
    assert index < len(planned) and planned[index]["name"] == step, (index, [w["name"] for w in planned])
    target = planned[index]["target"]
    assert fw["position"] != target, f"the arm reached the {step} target"
    reported = [e for e in e2e.events_named(events, "step_done") if e.get("name") == step]
    assert len(reported) == sum(1 for w in planned[:index] if w["name"] == step), f"{step} reported done"


def test_estop_request_mid_move(sim, daemon_factory):
    d = daemon_factory(sim.port)
    name = e2e.scene_labels()[0]
    replies = {}
    t, out, fired = start_pick(d, name, "carry", lambda: replies.update(estop=d.request({"cmd": "estop"})[1]))
    t.join(timeout=120)
    assert fired.is_set(), "the pick never reached the carry step"
    assert out["final"]["error"]["code"] == "estop", out["final"]
    assert e2e.events_named(out["events"], "estop"), [e["event"] for e in out["events"]]
    deadline = time.monotonic() + 10  # the estop's own reply races the pick's final line
    while "estop" not in replies and time.monotonic() < deadline:
        time.sleep(0.02)
    assert replies["estop"]["result"]["estop"] is True
    fw = assert_stopped(d, sim, "ESTOP_COMMAND")
    assert_interrupted(out["events"], sim, fw, "carry")
    # Refused while latched, usable again after clear_fault: home then ends exactly at the home pose.
    _, final = d.request({"cmd": "home"})
    assert final["error"]["code"] in ("fault", "estop"), final
    _, final = d.request({"cmd": "clear_fault"})
    assert "result" in final, final
    _, final = d.request({"cmd": "home"})
    home = e2e.home_steps(e2e.load_default_config()["arm"])
    assert final["result"]["position"] == home, final
    assert sim.moves()[-1]["target"] == home and sim.moves()[-1]["end"] == home


def test_estop_input_mid_move(sim, daemon_factory):
    d = daemon_factory(sim.port)
    name = e2e.scene_labels()[0]
    t, out, fired = start_pick(d, name, "lift", lambda: sim.control("estop 1"))
    t.join(timeout=120)
    assert fired.is_set()
    assert out["final"]["error"]["code"] == "estop", out["final"]
    assert e2e.events_named(out["events"], "estop")
    fw = assert_stopped(d, sim, "ESTOP_INPUT")
    assert_interrupted(out["events"], sim, fw, "lift")
    _, final = d.request({"cmd": "clear_fault"})
    assert final["error"]["code"] == "estop_active", final  # the input is still held
    sim.control("estop 0")
    time.sleep(0.1)
    _, final = d.request({"cmd": "clear_fault"})
    assert "result" in final, final
    _, final = d.request({"cmd": "home"})
    assert final["result"]["position"] == e2e.home_steps(e2e.load_default_config()["arm"]), final
