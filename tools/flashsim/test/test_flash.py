"""test_flash.py - flashing as users do, end to end: `make flash PORT=<pty>` (tools/flash's avrdude command, the
wiring/stk500v2 programmer) through Debian's Mega 2560 bootloader in rbx1-avrboard, to a blank board and over a
running firmware; the protocol harness against the flashed firmware; rbx1d ready on a freshly flashed board; an
EEPROM setting across the re-flash; a corrupted upload caught by avrdude's verify. Prints the upload times (wall and simulated).
Env: AVRBOARD, RBX1_SOURCE_DIR."""
import json
import os
import re
import shutil
import subprocess
import sys
import time

import pytest

SRC = os.environ.get("RBX1_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", ".."))
sys.path.insert(0, os.path.join(SRC, "protocol", "python"))
sys.path.insert(0, os.path.join(SRC, "tools", "harness"))
sys.path.insert(0, os.path.dirname(__file__))
from flip_proxy import FlipProxy  # noqa: E402
from rbx1proto.link import Link  # noqa: E402
from rbx1proto.messages import MsgType, Status  # noqa: E402
from rbx1_harness.sim_clock import SimClock  # noqa: E402

AVRBOARD = os.environ.get("AVRBOARD", os.path.join(SRC, "build", "bin", "rbx1-avrboard"))
BIN = os.path.dirname(AVRBOARD)
HEX = os.path.join(SRC, "build", "firmware", "rbx1.hex")
BOOTLOADER = "/usr/share/arduino/hardware/arduino/avr/bootloaders/stk500v2/stk500boot_v2_mega2560.hex"
BOOT_START = 0x3E000
MAX_SPEED, JOINT = 3, 0  # the EEPROM-stored setting: joint 1's MAX_SPEED (PROTOCOL.md keys)


def read_hex(path):
    """Intel HEX to {address: byte} (record types 00, 02, 04; others carry no data)."""
    data, base = {}, 0
    for line in open(path):
        line = line.strip()
        if not line.startswith(":"):
            continue
        raw = bytes.fromhex(line[1:])
        n, addr, kind = raw[0], (raw[1] << 8) | raw[2], raw[3]
        if kind == 0:
            for i in range(n):
                data[base + addr + i] = raw[4 + i]
        elif kind == 2:
            base = int.from_bytes(raw[4:6], "big") << 4
        elif kind == 4:
            base = int.from_bytes(raw[4:6], "big") << 16
    return data


class BoardRun:
    """rbx1-avrboard with its flash and EEPROM files in tmp; its stderr (resets, boot events) in a file."""

    # The board's own guard (--max-seconds 400, wall clock) stays just under ctest's TIMEOUT of 420 s: the module's
    # tests share it, and on a loaded machine they took more than the 220 s it once had (the board left mid-test).
    def __init__(self, tmp):
        self.flash, self.eeprom, self.log = tmp / "flash.bin", tmp / "eeprom.bin", tmp / "board.log"
        self.clock = tmp / "clock"  # the simulated time, which the harness counts its timeouts on
        self.err = open(self.log, "w")
        self.proc = subprocess.Popen([AVRBOARD, "--flash", str(self.flash), "--eeprom", str(self.eeprom),
                                      "--clock-file", str(self.clock), "--max-seconds", "400"],
                                     stdout=subprocess.PIPE, stderr=self.err, text=True)
        self.port = self.proc.stdout.readline().strip()
        assert self.port.startswith("/dev/pts/"), f"no pty path from rbx1-avrboard (got {self.port!r})"
        self.sim_clock = SimClock(self.clock)  # written before the pty path

    def events(self):
        return self.log.read_text()

    def now(self):
        """Seconds on the board's clock (its --clock-file): a loaded machine holds the simulation behind real time."""
        return self.sim_clock.seconds()

    def upload_seconds(self, since):
        """Simulated seconds from the last reset to the application's start (the bootloader leaves 0.1 s after
        avrdude's last command), in the log after offset since."""
        for _ in range(50):
            text = self.events()[since:]
            resets = [(m.start(), float(m.group(1))) for m in re.finditer(r"([\d.]+) s: reset, in the bootloader", text)]
            app = re.search(r"([\d.]+) s: bootloader left, application running", text[resets[-1][0]:]) if resets else None
            if app:
                return float(app.group(1)) - resets[-1][1]
            time.sleep(0.1)
        raise AssertionError(f"no reset followed by the application's start in the board's log:\n{text}")

    def link(self):
        """Opens the port as the daemon does; when that reset the board, returns once the board's log says the
        firmware runs. The bootloader takes the first byte it sees in its 0.83 s wait as an upload starting and then
        stays until 5 s pass without a byte, so a host must not talk before (PROTOCOL.md's HELLO would keep it)."""
        since = len(self.events())
        link = Link(self.port, timeout=0.3, retries=30)  # patient: a loaded machine slows the simulation
        link.clock = self.now  # and its timeouts count on the board's clock
        time.sleep(0.1)  # the board logs the open's reset within a slice of simulated time
        for _ in range(100):
            text = self.events()[since:]
            if "DTR asserted: reset" not in text or re.search(r"reset, in the bootloader.*bootloader left", text, re.S):
                # A new host starts a session with HELLO (PROTOCOL.md "Window"): a board that was not reset by
                # this open still remembers the last session's SEQs and would refuse this Link's first ones.
                link.hello()
                return link
            time.sleep(0.05)
        link.close()
        raise AssertionError(f"the firmware did not start after the reset:\n{text}")

    def stop(self):
        self.proc.terminate()
        assert self.proc.wait(timeout=10) == 0, self.events()
        self.sim_clock.close()
        self.err.close()


def make_flash(port):
    """`make flash PORT=port` as a user runs it, with arduino-cli off the PATH; (result, wall seconds)."""
    env = dict(os.environ)
    env.pop("MAKEFLAGS", None)  # not the jobserver of a make running the tests
    env["PATH"] = os.pathsep.join(d for d in env["PATH"].split(os.pathsep)
                                  if not os.path.exists(os.path.join(d, "arduino-cli")))
    t0 = time.monotonic()
    r = subprocess.run(["make", "-s", "-C", SRC, "flash", f"PORT={port}"], env=env, capture_output=True, text=True,
                       timeout=120)
    return r, time.monotonic() - t0


def config_get(board, joint, key):
    with board.link() as link:
        r = link.request(MsgType.CONFIG_GET, joint=joint, key=key)
        assert r["status"] == Status.OK, r
        return r["value"]


def daemon_ready_seconds(board):
    """rbx1d started right after a flash: its open resets the board (avrdude's close dropped DTR), and its
    handshake must let the bootloader leave (host/link: HELLO, then quiet) before the arm is ready."""
    since = len(board.events())
    sock = str(board.log.parent / "rbx1d.sock")
    t0 = time.monotonic()
    daemon = subprocess.Popen([os.path.join(BIN, "rbx1d"), "--config", os.path.join(SRC, "data", "rbx1.toml"),
                               "--port", board.port, "--socket", sock, "--console", "127.0.0.1:0",
                               "--state-dir", str(board.log.parent / "state")],  # never the machine's /var/lib/rbx1
                              stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True)
    try:
        status = {}
        while time.monotonic() - t0 < 60:
            r = subprocess.run([os.path.join(BIN, "rbx1"), "status", "--json", "--socket", sock], capture_output=True,
                               text=True, timeout=20)
            if r.returncode == 0:
                status = json.loads(r.stdout.strip().splitlines()[-1])["result"]
                if status["ready"]:
                    break
            time.sleep(0.2)
        ready = time.monotonic() - t0
        assert status.get("ready"), f"rbx1d not ready after 60 s: {status}"
    finally:
        daemon.terminate()
        daemon.wait(timeout=10)
    assert "DTR asserted: reset" in board.events()[since:]
    return ready


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    assert os.path.exists(HEX), f"{HEX} missing: run make firmware"
    b = BoardRun(tmp_path_factory.mktemp("avrboard"))
    yield b
    b.stop()


def test_blank_board_holds_only_the_bootloader(board):
    time.sleep(0.2)  # the flash file exists once the board runs
    flash = board.flash.read_bytes()
    assert len(flash) == 256 * 1024
    assert flash[:BOOT_START] == b"\xff" * BOOT_START
    boot = read_hex(BOOTLOADER)
    assert min(boot) == BOOT_START and all(flash[a] == v for a, v in boot.items())


def test_make_flash_uploads_to_a_blank_board(board):
    since = len(board.events())
    r, wall = make_flash(board.port)
    assert r.returncode == 0, r.stdout + r.stderr + "\nthe board's log:\n" + board.events()[since:]
    fw = read_hex(HEX)
    assert f"{len(fw)} bytes of flash verified" in r.stderr, r.stderr
    sim = board.upload_seconds(since)
    flash = board.flash.read_bytes()
    assert all(flash[a] == v for a, v in fw.items()), "the flash file does not hold rbx1.hex"
    print(f"\nupload to a blank board: {len(fw)} bytes, make flash {wall:.2f} s wall, reset to firmware start "
          f"{sim:.2f} s simulated")


def test_harness_passes_against_the_flashed_firmware(board):
    # avrdude's close dropped DTR: the harness's open resets the board, and --boot-wait lets the bootloader leave.
    since = len(board.events())
    r = subprocess.run([sys.executable, os.path.join(SRC, "tools", "rbx1-harness"), "--port", board.port,
                        "--boot-wait", "3", "--clock-file", str(board.clock)],  # on the board's clock
                       capture_output=True, text=True, timeout=150)
    assert "DTR asserted: reset" in board.events()[since:]
    assert r.returncode == 0 and "FAIL" not in r.stdout, r.stdout + r.stderr
    assert re.search(r"^([2-9]\d) passed, 0 failed", r.stdout, re.M), r.stdout


def test_reflash_over_running_firmware_keeps_eeprom(board):
    with board.link() as link:
        # Not the default 4000, and not below the bundled config's 4000 (rbx1d refuses a board slower than its config).
        r = link.request(MsgType.CONFIG_SET, joint=JOINT, key=MAX_SPEED, value=5432)
        assert r["status"] == Status.OK, r
    since = len(board.events())
    r, wall = make_flash(board.port)  # the Link closed with HUPCL clear: tools/flash's stty makes avrdude reset it
    assert r.returncode == 0, r.stdout + r.stderr
    assert "bytes of flash verified" in r.stderr, r.stderr
    sim = board.upload_seconds(since)
    print(f"\nupload over the running firmware: make flash {wall:.2f} s wall, reset to firmware start {sim:.2f} s "
          f"simulated")
    ready = daemon_ready_seconds(board)
    print(f"rbx1d ready on the freshly flashed board after {ready:.1f} s (its open reset the board)")
    assert config_get(board, JOINT, MAX_SPEED) == 5432  # the bootloader never touched the EEPROM


def test_daemon_style_close_keeps_the_board_running(board):
    """A port closed with HUPCL clear (rbx1d, rbx1proto's Link) keeps DTR asserted: reopening does not reset."""
    config_get(board, JOINT, MAX_SPEED)  # leaves the port closed with HUPCL clear
    since = len(board.events())
    with Link(board.port, timeout=0.3, retries=10) as link:
        link.clock = board.now
        t0 = board.now()
        link.hello()  # at once: a reset board would sit in its bootloader and not answer
        assert board.now() - t0 < 1.0
    assert "DTR asserted: reset" not in board.events()[since:], board.events()[since:]


def test_corrupted_upload_is_caught_by_verify(board):
    proxy = FlipProxy(board.port)
    try:
        env = dict(os.environ)
        env.pop("MAKEFLAGS", None)
        r = subprocess.run([os.path.join(SRC, "tools", "flash"), proxy.port], env=env, capture_output=True, text=True,
                           timeout=120)
    finally:
        proxy.close()
    assert proxy.flipped_at is not None, "the proxy saw no flash page go by:\n" + r.stderr
    assert r.returncode != 0, r.stderr
    m = re.search(r"verification mismatch\s+device 0x[0-9a-f]+ != input 0x[0-9a-f]+ at addr 0x([0-9a-f]+)", r.stderr)
    assert m and int(m.group(1), 16) == proxy.flipped_at, r.stderr
    assert f"flash: upload to {proxy.port} failed" in r.stderr, r.stderr
    fw = read_hex(HEX)
    flash = board.flash.read_bytes()
    a = proxy.flipped_at
    assert flash[a] == fw[a] ^ 1 and flash[a + 1] == fw[a + 1] ^ 1  # what the bootloader was sent, it wrote


@pytest.mark.parametrize("args, message", [
    (["--flash", "/nonexistent/dir/flash.bin"], "/nonexistent/dir/flash.bin: No such file or directory"),
    (["--bootloader", "/nonexistent.hex"], "/nonexistent.hex: cannot read the bootloader HEX"),
    (["--bootloader", HEX], ": not a boot-section image"),
])
def test_bad_arguments_one_clear_line(tmp_path, args, message):
    full = args if "--flash" in args else ["--flash", str(tmp_path / "flash.bin")] + args
    r = subprocess.run([AVRBOARD] + full, capture_output=True, text=True, timeout=10)
    assert r.returncode == 2 and r.stdout == "", r
    lines = [l for l in r.stderr.splitlines() if not l.startswith("read_ihex_chunks:")]
    assert len(lines) == 1 and lines[0].startswith("rbx1-avrboard: ") and message in lines[0], r.stderr
