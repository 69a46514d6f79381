"""test_absent.py - the paper's rule: a requested object that is not in the scene sends the arm home and the job
fails with an error naming it."""
import shutil
import subprocess
import sys

import rbx1e2e as e2e
from conftest import fast_config
from rbx1e2e import ok


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


def test_untaught_look_alike_is_absent_with_the_reason(sim, daemon_factory, tmp_path):
    """Issue 27: the plate is taught, only its twin 10 % longer lies on the table. Today's global 0.5 took the twin
    for the plate (and picked it); now it is unknown and the pick by name answers object_absent saying why."""
    sys.path.insert(0, str(e2e.ROOT / "tools" / "scenegen"))
    from scenegen import scene as sg  # the scene generator renders both with exact truth
    for name in ("plate", "plate_long"):
        image, background, doc = sg.teach_image(name, size=(640, 480), seed=3)
        sg.write(str(tmp_path / name), image, background, doc)
    lib = tmp_path / "library.json"
    shutil.copy(e2e.DEMO / "library.json", lib)
    r = subprocess.run([e2e.BIN / "rbx1", "teach", tmp_path / "plate.png", "--name", "plate", "--library", lib,
                        "--background", tmp_path / "plate.bg.png", "--px-per-cm", "40"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    cfg = fast_config()
    cfg["camera"]["device"] = str(tmp_path / "plate_long.png")
    cfg["vision"].update(background=str(tmp_path / "plate_long.bg.png"), library=str(lib))
    d = daemon_factory(sim.port, cfg)
    _, scan = ok(d, {"cmd": "scan"})
    (o,) = scan["detections"]["objects"]
    ident = o["identification"]
    assert o["label"] is None and ident["best"] == "plate", ident
    assert 0.5 <= ident["best_score"] < ident["threshold"], ident  # over today's 0.5: it would have been picked
    events, final = d.request({"cmd": "pick", "name": "plate", "place": "tray"})
    assert final["error"]["code"] == "object_absent", final
    msg = final["error"]["message"]
    assert f"not taken as it: #1 matches it {ident['best_score']:.2f}, below its taught {ident['threshold']:.2f}" in msg
    absent = [e for e in events if e["event"] == "absent"][0]
    assert absent["look_alikes"].startswith("#1 matches it"), absent
    assert "planned" not in [e["event"] for e in events]
