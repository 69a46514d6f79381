"""test_absent.py - the paper's rule: a requested object that is not in the scene sends the arm home and the job
fails with an error naming it."""
import subprocess

import rbx1e2e as e2e
from conftest import fast_config


def test_absent_object_goes_home_and_names_it(sim, daemon_factory):
    cfg = fast_config()
    cfg["camera"]["device"] = str(e2e.DEMO / "background.png")  # the empty table: nothing to pick
    d = daemon_factory(sim.port, cfg)
    name = e2e.scene_labels()[0]
    events, final = d.request({"cmd": "pick", "name": name, "place": "tray"})
    assert final["error"]["code"] == "object_absent", final
    assert f'"{name}"' in final["error"]["message"]
    names = [e["event"] for e in events]
    assert "detected" in names and "absent" in names and "planned" not in names, names
    # Executed: the move to the scan pose, then home; nothing else.
    log = sim.moves()
    home = [0] * 6
    assert [e["kind"] for e in log] == ["move", "move"], log
    assert log[-1]["target"] == home and log[-1]["end"] == home
    _, st = d.request({"cmd": "status"})
    assert st["result"]["firmware"]["position"] == home
    # The CLI reports it as a job error: exit 1, the message on stderr.
    r = subprocess.run([e2e.BIN / "rbx1", "pick", name, "--place", "tray", "--socket", d.socket],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and "object_absent" in r.stderr and name in r.stderr


def test_unknown_label_is_absent_too(sim, daemon_factory):
    d = daemon_factory(sim.port)
    events, final = d.request({"cmd": "pick", "name": "unicorn", "place": "tray"})
    assert final["error"]["code"] == "object_absent"
    assert '"unicorn"' in final["error"]["message"]
    assert sim.moves()[-1]["target"] == [0] * 6
