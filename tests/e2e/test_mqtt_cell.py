"""test_mqtt_cell.py - arms on one real mosquitto: three daemons, each on its own rbx1-simfw, with their own
users under the broker's ACL. A command to one arm never reaches another, a pick sent through the broker to each
completes (checked in each firmware's move log), a daemon killed with -9 is shown offline through its will while
the others go on, and tools/cell refuses a job for it. A broker restart mid-pick changes nothing in the pick.
Home Assistant's recipe select and Sort button run a sort whose `pick` messages are its history rows."""
import json
import signal
import subprocess
import time

import pytest

import mqttkit
import rbx1e2e as e2e
from conftest import fast_config

ARMS = ["arm1", "arm2", "arm3"]
# Job events reach MQTT through the daemon's bus (Machine::bus()).
EVENTS_FROM_BUS = True


@pytest.fixture
def broker(tmp_path):
    b = mqttkit.Broker(tmp_path, ARMS)
    yield b
    b.stop()


def start_arm(tmp_path, broker, name, daemon=None, **mqtt):
    d = tmp_path / name
    d.mkdir()
    sim = e2e.Simfw(d, "--eeprom", d / "eeprom.bin")
    e2e.configure_fast_firmware(sim.port)
    cfg = fast_config()
    cfg["daemon"]["arm_id"] = name
    cfg["daemon"].update(daemon or {})
    cfg["mqtt"] = mqttkit.mqtt_section(broker, name, **mqtt)
    return sim, e2e.Daemon(d, cfg, sim.port)


def test_three_arms_on_one_broker(tmp_path, broker):
    arms = {}
    watch = mqttkit.Watcher(broker)
    try:
        for name in ARMS:
            arms[name] = start_arm(tmp_path, broker, name)
        for name in ARMS:
            watch.wait_status(name, "online")
            state = json.loads(watch.wait(lambda t, p, r, n=name: t == f"rbx1/{n}/state" and
                                          json.loads(p).get("ready"), what=f"{name} ready state")[1])
            assert state["arm_id"] == name and state["mode"] == "ready", state
        code, out, _ = mqttkit.cell(broker, "list", "--json")
        listed = json.loads(out)
        assert code == 0 and all(listed[n]["status"] == "online" for n in ARMS), listed

        # One pick per arm through the broker; only that arm's firmware moves.
        label = e2e.scene_labels()[0]
        for name in ARMS:
            before = {n: len(arms[n][0].moves()) for n in ARMS}
            code, out, err = mqttkit.cell(broker, "pick", name, label, "--place", "tray")
            assert code == 0, (name, out, err)
            assert "result" in mqttkit.reply_of(out), out
            after = {n: len(arms[n][0].moves()) for n in ARMS}
            assert after[name] > before[name] + 5, (name, before, after)
            assert all(after[n] == before[n] for n in ARMS if n != name), (name, before, after)
            if EVENTS_FROM_BUS:
                watch.wait(lambda t, p, r, n=name: t == f"rbx1/{n}/event" and json.loads(p).get("final") and
                           json.loads(p).get("cmd") == "pick", what=f"{name}'s pick's final event")
                # A single pick is not in the history (sorts and clears are): no `pick` message.
                assert f"rbx1/{name}/pick" not in watch.topics()

        # kill -9 one daemon: its will says offline; the others stay online and keep answering.
        victim_sim, victim = arms["arm3"]
        t0 = time.monotonic()
        victim.proc.send_signal(signal.SIGKILL)
        victim.proc.wait()
        watch.wait_status("arm3", "offline", timeout=1.5 * 5 + 5)
        print(f"kill -9 to offline: {time.monotonic() - t0:.2f} s (keepalive_s 5)")
        assert watch.last("rbx1/arm1/status") == "online" and watch.last("rbx1/arm2/status") == "online"
        code, out, err = mqttkit.cell(broker, "pick", "arm3", label, "--place", "tray", timeout=30)
        assert code == 3 and "offline" in err, (code, out, err)
        code, out, err = mqttkit.cell(broker, "send", "arm2", '{"cmd":"status"}', timeout=30)
        assert code == 0 and mqttkit.reply_of(out)["result"]["ready"], (out, err)
        # A stop over MQTT (a protective stop, not an emergency stop) latches on that arm only, shown in its state.
        code, out, err = mqttkit.cell(broker, "send", "arm1", '{"cmd":"estop"}', timeout=30)
        assert code == 0 and mqttkit.reply_of(out)["result"]["estop"], (out, err)
        watch.wait(lambda t, p, r: t == "rbx1/arm1/state" and json.loads(p)["mode"] == "estop", what="arm1 estop")
        assert json.loads(watch.last("rbx1/arm2/state"))["mode"] == "ready"
    finally:
        watch.close()
        for sim, d in arms.values():
            d.stop()
            sim.stop()


def test_broker_restart_mid_pick_changes_nothing(tmp_path, broker):
    sim, d = start_arm(tmp_path, broker, "arm1")
    watch = mqttkit.Watcher(broker)
    try:
        watch.wait_status("arm1", "online")
        label = e2e.scene_labels()[0]
        # A reference pick over the socket: the moves an undisturbed pick makes.
        before = len(sim.moves())
        _, final = d.request({"cmd": "pick", "name": label, "place": "tray"})
        assert "result" in final, final
        reference = [m["end"] for m in sim.moves()[before:]]

        # The same pick sent over MQTT; the broker goes away once the arm moves, and comes back.
        before = len(sim.moves())
        import subprocess
        tool = subprocess.Popen(["/usr/bin/python3", str(mqttkit.CELL_TOOL), "--host", "127.0.0.1", "--port",
                                 str(broker.port), "--username", "controller", "--password-file",
                                 broker.password_file("controller"), "pick", "arm1", label, "--place", "tray",
                                 "--timeout", "100"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 60
        while len(sim.moves()) < before + 3:
            assert time.monotonic() < deadline, "the pick sent over MQTT never moved the arm"
            time.sleep(0.02)
        broker.stop()
        time.sleep(1.5)
        broker.start()
        # The pick ran to its end regardless of the broker (the socket's status shows it done)...
        deadline = time.monotonic() + 60
        while e2e.status(d)["job"] is not None:
            assert time.monotonic() < deadline
            time.sleep(0.1)
        assert [m["end"] for m in sim.moves()[before:]] == reference
        tool.kill()  # its own subscription to the reply died with the broker (paho does not resubscribe)
        tool.communicate()
        # ...and the daemon reconnected and republished status and state (the broker kept nothing).
        fresh = mqttkit.Watcher(broker)
        try:
            fresh.wait_status("arm1", "online", timeout=40)
            st = json.loads(fresh.wait(lambda t, p, r: t == "rbx1/arm1/state", timeout=10)[1])
            assert st["mqtt"]["connects"] >= 2, st
        finally:
            fresh.close()
    finally:
        watch.close()
        d.stop()
        sim.stop()


def test_recipe_select_sort_button_and_pick_rows(tmp_path, broker):
    """A recipe saved over MQTT appears in Home Assistant's select; choosing it moves nothing; the Sort button runs
    a sort with it; each of the sort's pick attempts is one `pick` message equal to its row of
    `rbx1 history --json`. pick_retries 0 on the static scene: one attempt (still there: failed), then the object
    is given up (a skipped row) and the sort is done."""
    sim, d = start_arm(tmp_path, broker, "arm1", daemon={"pick_retries": 0}, homeassistant=True)
    watch = mqttkit.Watcher(broker, topics=("rbx1/#", "homeassistant/#"))
    try:
        watch.wait_status("arm1", "online")
        online = time.monotonic()
        label = e2e.scene_labels()[0]
        code, out, err = mqttkit.cell(broker, "send", "arm1", json.dumps(
            {"cmd": "recipe_save", "name": "first", "recipe": {label: "tray"}}), timeout=30)
        assert code == 0, (out, err)
        select = "homeassistant/select/arm1/recipe/config"
        watch.wait(lambda t, p, r: t == select and p and json.loads(p)["options"] == ["first"], timeout=5,
                   what="the select offering the saved recipe")

        moves = len(sim.moves())
        watch.c.publish("rbx1/arm1/recipe/set", "first", qos=1)
        watch.wait(lambda t, p, r: t == "rbx1/arm1/recipe" and p == "first", what="the choice shown")
        time.sleep(1.0)
        assert len(sim.moves()) == moves and e2e.status(d)["job"] is None, "choosing a recipe moved the arm"

        time.sleep(max(0.0, online + 2.2 - time.monotonic()))  # a press right after the connect is refused stale
        watch.c.publish("rbx1/arm1/recipe/sort", "PRESS", qos=1)
        _, payload, _ = watch.wait(lambda t, p, r: t == "rbx1/arm1/cmd/response" and "result" in json.loads(p),
                                   timeout=180, what="the sort's result")
        summary = json.loads(payload)["result"]
        assert summary["recipe"] == "first" and summary["attempts"] == 1, summary
        assert len(sim.moves()) > moves + 5

        rows = json.loads(subprocess.run([e2e.need(e2e.BIN / "rbx1"), "history", "--json", "--job",
                                          str(summary["job"]), "--socket", d.socket], capture_output=True,
                                         text=True, timeout=30, check=True).stdout)["picks"]
        attempts = [r for r in rows if r["outcome"] != "skipped"]
        assert [(r["outcome"], r["reason"], r["class"]) for r in attempts] == [("failed", "still_there", label)], rows
        watch.wait(lambda t, p, r: watch.topics().count("rbx1/arm1/pick") >= len(rows), what="the pick messages")
        time.sleep(0.5)  # one message too many would be here by now
        with watch.lock:
            picks = [json.loads(p) for t, p, _ in watch.messages if t == "rbx1/arm1/pick"]
        assert picks == rows[::-1], (picks, rows)  # one message per row, as written (the history: newest first)
    finally:
        watch.close()
        d.stop()
        sim.stop()
