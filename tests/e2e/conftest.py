"""conftest.py - fixtures: a fast simulated arm (rbx1-simfw with raised speed limits) and rbx1d on it."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import rbx1e2e as e2e  # noqa: E402


def fast_config(cfg=None):
    """The bundled config, paths absolute, with a faster arm so a pick takes seconds, not a minute."""
    cfg = e2e.absolutize(cfg or e2e.load_default_config())
    e2e.fast_arm(cfg)
    cfg.setdefault("daemon", {})["log_level"] = "debug"
    return cfg


@pytest.fixture
def sim(tmp_path):
    s = e2e.Simfw(tmp_path, "--eeprom", tmp_path / "eeprom.bin")
    try:
        e2e.configure_fast_firmware(s.port)
        yield s
    finally:
        s.stop()


@pytest.fixture
def daemon_factory(tmp_path):
    started = []

    def start(port, cfg=None, **kw):
        d = e2e.Daemon(tmp_path, cfg if cfg is not None else fast_config(), port, **kw)
        started.append(d)
        return d

    yield start
    for d in started:
        d.stop()
