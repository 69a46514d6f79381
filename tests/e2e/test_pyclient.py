"""test_pyclient.py - the Python client library (host/python/rbx1) against rbx1d and rbx1-simfw: the README's example
run as it stands, from a checkout; the web console's HTTP API with its token and error classes."""
import os
import re
import subprocess

import pytest

import rbx1e2e as e2e
from conftest import fast_config

rbx1 = e2e.rbx1
README = e2e.ROOT / "host" / "python" / "README.md"
TOKEN = "e2e-console-token-0123"


def readme_example():
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
    assert blocks, f"{README}: no python example"
    return blocks[0]


def test_readme_example_runs_against_the_daemon(sim, daemon_factory):
    d = daemon_factory(sim.port)
    env = dict(os.environ, RBX1_SOCKET=d.socket, PYTHONPATH=str(e2e.ROOT / "host" / "python"))
    r = subprocess.run([e2e.sys.executable, "-c", readme_example()], env=env, capture_output=True, text=True,
                       timeout=180, cwd="/")
    assert r.returncode == 0, r.stdout + r.stderr
    out = r.stdout.splitlines()
    assert out[0] == "ready: True", out
    labels = e2e.scene_labels()
    assert sorted(line.split()[1] for line in out[1:1 + len(labels)]) == sorted(labels), out
    events = [line.split()[0] for line in out[1 + len(labels):] if not line.startswith(("picked:", "absent:", "home:"))]
    for needed in ("job_started", "captured", "detected", "identified", "planned", "sent", "step", "step_done"):
        assert needed in events, (needed, out)
    assert f"picked: {out[1].split()[1]}" in out, out  # the first object detected, picked
    assert any(line.startswith('absent: object "unicorn" is not in the scene') for line in out), out
    assert "home: job_started" in out, out
    st = rbx1.Arm(socket=d.socket).status()
    assert st["ready"] and st["firmware"]["position"] == e2e.home_steps(e2e.load_default_config()["arm"]), st


def test_console_http_api_with_its_token(sim, daemon_factory):
    cfg = fast_config()
    cfg["console"] = {"bind": "127.0.0.1:0", "token": TOKEN}
    d = daemon_factory(sim.port, cfg)
    url = d.console_url()
    arm = rbx1.Arm(url=url, token=TOKEN)
    assert arm.status()["ready"] is True
    assert rbx1.Arm(url=url).status()["ready"] is True  # reading is free on a loopback bind
    before = len(sim.moves())
    for anonymous in (rbx1.Arm(url=url), rbx1.Arm(url=url, token="not-the-token-0000")):
        with pytest.raises(rbx1.Unauthorized):
            anonymous.home()
    with pytest.raises(rbx1.UnknownPlace) as e:
        arm.pick("bolt", "moon")
    assert '"moon"' in e.value.message and e.value.code == "unknown_place"
    with pytest.raises(rbx1.NotAllowed):
        arm.shutdown()
    with pytest.raises(rbx1.UnknownCommand):
        arm.request("teleport")
    assert len(sim.moves()) == before, "a refused request moved the arm"
    seen = []
    result = arm.scan(on_event=seen.append)
    assert sorted(o["label"] for o in result["detections"]["objects"]) == sorted(e2e.scene_labels())
    assert [e["event"] for e in seen if e["event"] in ("captured", "detected")] == ["captured", "detected"], seen
    assert arm.home()["position"] == e2e.home_steps(e2e.load_default_config()["arm"])
