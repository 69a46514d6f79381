"""test_config_cli.py - rbx1d --check-config, config errors naming keys, malformed control requests, CLI exit codes."""
import json
import os
import subprocess

import rbx1e2e as e2e
from conftest import fast_config


def run(*args, **kw):
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=60, **kw)


def test_bundled_config_checks_ok():
    r = run(e2e.need(e2e.BIN / "rbx1d"), "--config", e2e.DATA / "rbx1.toml", "--check-config")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "OK"


def test_config_errors_name_each_key(tmp_path):
    cfg = fast_config()
    cfg["camra"] = {"device": "x"}                      # misspelt table
    cfg["daemon"]["home_on_start"] = "jump"
    cfg["daemon"]["colour"] = "red"
    cfg["link"]["baud"] = 9600
    cfg["arm"]["joints"]["j3"]["min_deg"] = 500.0
    path = e2e.write_config(tmp_path, cfg)
    r = run(e2e.BIN / "rbx1d", "--config", path, "--check-config")
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    for key in ("camra", "daemon.home_on_start", "daemon.colour", "link.baud", "arm.joints.j3.min_deg"):
        assert any(f": {key}" in l or f" {key}:" in l for l in lines), (key, r.stderr)
    assert len(lines) == 5, r.stderr


def test_check_config_opens_what_the_daemon_would(tmp_path):
    """A missing library or camera file, an unreadable library and px_per_cm = 0 are errors naming the key, not OK."""
    cases = {
        "vision.library": lambda c: c["vision"].update(library=str(tmp_path / "nope.json")),
        "camera.device": lambda c: c["camera"].update(device=str(tmp_path / "nope.png")),
        "vision.px_per_cm": lambda c: c["vision"].update(px_per_cm=0.0),
    }
    for key, change in cases.items():
        cfg = fast_config()
        change(cfg)
        path = e2e.write_config(tmp_path, cfg)
        r = run(e2e.BIN / "rbx1d", "--config", path, "--check-config")
        assert r.returncode == 2 and r.stdout == "", (key, r.stdout, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and f": {key}: " in lines[0], (key, r.stderr)
    garbage = tmp_path / "library.json"
    garbage.write_text("{not json")
    cfg = fast_config()
    cfg["vision"]["library"] = str(garbage)
    r = run(e2e.BIN / "rbx1d", "--config", e2e.write_config(tmp_path, cfg), "--check-config")
    assert r.returncode == 2 and ": vision: " in r.stderr and "library.json" in r.stderr, r.stderr


def test_check_syntax_opens_nothing(tmp_path):
    """--check-syntax (a config for another machine) checks keys and values only: missing files pass, bad keys not."""
    cfg = fast_config()
    cfg["vision"]["library"] = str(tmp_path / "nope.json")
    cfg["camera"]["device"] = "/dev/video99"
    path = e2e.write_config(tmp_path, cfg)
    r = run(e2e.BIN / "rbx1d", "--config", path, "--check-syntax")
    assert r.returncode == 0 and r.stdout == "OK\n", r.stderr
    r = run(e2e.BIN / "rbx1d", "--config", path, "--check-config")
    assert r.returncode == 2 and ": vision.library: " in r.stderr and ": camera.device: " in r.stderr, r.stderr
    cfg["daemon"]["home_on_start"] = "jump"
    r = run(e2e.BIN / "rbx1d", "--config", e2e.write_config(tmp_path, cfg), "--check-syntax")
    assert r.returncode == 2 and "daemon.home_on_start" in r.stderr, r.stderr


def test_unreadable_config_exits_2(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[daemon\nsocket = 1\n")
    r = run(e2e.BIN / "rbx1d", "--config", bad, "--check-config")
    assert r.returncode == 2 and "bad.toml" in r.stderr
    r = run(e2e.BIN / "rbx1d", "--config", tmp_path / "missing.toml", "--check-config")
    assert r.returncode == 2 and "missing.toml" in r.stderr


def raw(sock_path, data):
    """The reply to bytes written as they are (the client's raw-line path: no JSON encoding of ours)."""
    return e2e.rbx1.Arm(socket=sock_path).send(data, timeout=10).wait()


def test_malformed_requests_get_errors_and_the_daemon_lives(sim, daemon_factory):
    d = daemon_factory(sim.port)
    assert oct(os.stat(d.socket).st_mode & 0o777) == "0o660"
    cases = [
        (b"{nope\n", "bad_json"),
        (b"[1]\n", "bad_request"),
        (b'{"cmd":"teleport"}\n', "unknown_command"),
        (b'{"cmd":"pick","name":"x"}\n', "missing_field"),
        (b'{"cmd":"pick","name":5,"place":"tray"}\n', "bad_field"),
        (b"x" * 70000 + b"\n", "line_too_long"),
        (b"\xff\xfe\x00\n", "bad_json"),
    ]
    for data, code in cases:
        assert raw(d.socket, data)["error"]["code"] == code, data[:40]
    _, final = d.request({"cmd": "status"})
    assert final["result"]["ready"] is True
    assert d.proc.poll() is None


def test_cli_exit_codes_and_output(sim, daemon_factory, tmp_path):
    d = daemon_factory(sim.port)
    rbx1 = e2e.need(e2e.BIN / "rbx1")
    r = run(rbx1, "status", "--socket", d.socket, "--json")
    assert r.returncode == 0, r.stderr
    final = json.loads(r.stdout.strip().splitlines()[-1])
    assert final["result"]["link"]["connected"] is True
    r = run(rbx1, "status", "--socket", tmp_path / "nobody.sock")
    assert r.returncode == 2 and "nobody.sock" in r.stderr
    r = run(rbx1, "pick", "bolt", "--place", "moon", "--socket", d.socket)
    assert r.returncode == 1 and "unknown_place" in r.stderr
    r = run(rbx1, "pick", "bolt", "--socket", d.socket)
    assert r.returncode == 2  # --place is required: usage error
    r = run(rbx1, "home", "--socket", d.socket)
    assert r.returncode == 0, r.stderr
    assert "job_started" in r.stdout and "position" in r.stdout
    r = run(rbx1, "shutdown", "--socket", d.socket)
    assert r.returncode == 0
    assert d.proc.wait(timeout=10) == 0


def test_bundled_arm_table_is_the_kinematics_defaults():
    """data/rbx1.toml carries host/arm/defaults.toml word for word: one source for the arm's defaults."""
    bundled = (e2e.DATA / "rbx1.toml").read_text()
    defaults = (e2e.ROOT / "host" / "arm" / "defaults.toml").read_text()
    start = defaults.index("# [arm]")
    assert bundled[bundled.index("# [arm]"):] == defaults[start:], \
        "data/rbx1.toml: replace everything from '# [arm]' on with the same part of host/arm/defaults.toml"
