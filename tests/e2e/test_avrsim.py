"""test_avrsim.py - one full pick against the real firmware ELF under simavr (rbx1-avrsim): the STEP pulses it
counted per joint equal what the commanded targets require (sum of |target - previous target|), and the net
signed count equals the final position."""
import json

import rbx1e2e as e2e
from conftest import fast_config

AVR_DEG_S = 40.0  # slower than the simfw tests: the real step ISR under simavr, paced to real time


def test_full_pick_on_the_real_firmware(tmp_path, daemon_factory):
    e2e.need(e2e.ROOT / "build" / "firmware" / "rbx1.elf")  # both made by the build: missing is a failure
    e2e.need(e2e.BIN / "rbx1-avrsim")
    out_json = tmp_path / "avrsim.json"
    sim = e2e.Simfw(tmp_path, "--json", out_json, "--eeprom", tmp_path / "eeprom.bin", exe="rbx1-avrsim",
                    log_moves=False)
    try:
        e2e.configure_fast_firmware(sim.port)
        cfg = fast_config()
        cfg["arm"]["speeds"]["joint_speed_deg_s"] = AVR_DEG_S
        d = daemon_factory(sim.port, cfg)
        name = e2e.scene_labels()[0]
        events, final = d.request({"cmd": "pick", "name": name, "place": "tray"}, timeout=180)
        assert "result" in final, final
        d.stop()
    finally:
        sim.stop()
    counted = json.loads(out_json.read_text())
    # Every move the daemon commanded, in order: the scan pose, then the plan's moves.
    targets = [e["target"] for e in e2e.events_named(events, "step_done") if e["kind"] == "move"]
    assert len(targets) == 1 + sum(1 for w in e2e.planned_waypoints(events) if w["kind"] == "move")
    start = [0] * 6  # declared at the home pose
    expected = [0] * 6
    prev = start
    for t in targets:
        expected = [x + abs(a - b) for x, a, b in zip(expected, t, prev)]
        prev = t
    assert counted["pulses"] == expected, (counted, expected)
    assert counted["steps"] == [a - b for a, b in zip(final["result"]["position"], start)]
    assert sum(expected) > 10000  # a real pick moved the joints
