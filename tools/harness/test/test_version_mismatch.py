"""test_version_mismatch.py - a firmware of another protocol version (a fake on a pty that answers HELLO as a
firmware speaking version PROTO_VERSION + 1 does: BAD_VERSION, its own version; one speaking version 4, which
reads our frames and answers in frames without parity; and one speaking version 3, whose CRC-16 frames NAK our
CRC-32 ones) meets the harness and rbx1d: both name the two versions and the command that fixes it.
Env: RBX1_SOURCE_DIR, RBX1_BIN_DIR."""
import binascii
import json
import os
import select
import subprocess
import sys
import threading
import time
import tty
import zlib

import pytest

SRC = os.environ.get("RBX1_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", ".."))
BIN = os.environ.get("RBX1_BIN_DIR", os.path.join(SRC, "build", "bin"))
sys.path.insert(0, os.path.join(SRC, "protocol", "python"))
from rbx1proto import frame, messages  # noqa: E402
from rbx1proto.messages import MsgType, Status  # noqa: E402

THEIRS = messages.PROTO_VERSION + 1


class OtherVersionFirmware:
    """Answers every HELLO with BAD_VERSION and version self.version (THEIRS); stays silent to everything else."""

    version = THEIRS

    def __init__(self):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.port = os.ttyname(self.slave)
        self.hellos = 0
        self.stop_r, self.stop_w = os.pipe()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        decoder = frame.Decoder()
        while True:
            ready, _, _ = select.select([self.master, self.stop_r], [], [])
            if self.stop_r in ready:
                return
            for f in decoder.feed(os.read(self.master, 256)):
                if getattr(f, "type", None) == MsgType.HELLO:
                    self.hellos += 1
                    os.write(self.master, self.hello_answer(f.seq))

    def hello_answer(self, seq):
        payload = messages.pack_response(
            MsgType.HELLO, status=Status.BAD_VERSION, proto_version=self.version, fw_major=9, fw_minor=0,
            fw_patch=0, joints=messages.JOINTS, queue_size=16, capabilities=0, last_seq=0, window=8)
        return frame.encode(seq, MsgType.HELLO | 0x80, payload)

    def close(self):
        os.write(self.stop_w, b"x")
        self.thread.join(5)
        for fd in (self.master, self.slave, self.stop_r, self.stop_w):
            os.close(fd)


class Version3Firmware(OtherVersionFirmware):
    """Frames as protocol version 3 did (CRC-16/CCITT-FALSE, 6 bytes): it reads LEN+6 bytes after a SYNC, finds
    our CRC-32 frame's CRC wrong and NAKs it BAD_CRC with its SEQ, then hunts again after that SYNC."""

    def _run(self):
        buf = bytearray()
        while True:
            ready, _, _ = select.select([self.master, self.stop_r], [], [])
            if self.stop_r in ready:
                return
            buf += os.read(self.master, 256)
            while True:
                i = buf.find(frame.SYNC)
                del buf[:max(i, 0) if i >= 0 else len(buf)]
                if len(buf) < 3 or len(buf) < buf[1] + 6:
                    break
                n, seq = buf[1], buf[2]
                if buf[1] <= frame.MAX_PAYLOAD and binascii.crc_hqx(bytes(buf[1:n + 4]), 0xFFFF) != \
                        buf[n + 4] | (buf[n + 5] << 8):
                    self.hellos += buf[3] == MsgType.HELLO
                    body = bytes([1, seq, MsgType.NAK, Status.BAD_CRC])
                    crc = binascii.crc_hqx(body, 0xFFFF)
                    os.write(self.master, bytes([frame.SYNC]) + body + bytes([crc & 0xFF, crc >> 8]))
                del buf[:1]


class Version4Firmware(OtherVersionFirmware):
    """Frames as protocol version 4 did (CRC-32, 8 bytes, no parity): after a SYNC it reads LEN+7 bytes, finds our
    CRC where it looks (our parity follows it, and is hunted past), answers HELLO BAD_VERSION with version 4 in a
    frame without parity, NAKs a bad CRC BAD_CRC and hunts again after that SYNC; a partial frame is dropped after
    50 ms of silence."""

    version = 4

    def _run(self):
        buf = bytearray()
        while True:
            ready, _, _ = select.select([self.master, self.stop_r], [], [], 0.05)
            if self.stop_r in ready:
                return
            if not ready:  # the inter-byte timeout: the partial frame's SYNC goes, the rest is scanned again
                del buf[:1]
            else:
                buf += os.read(self.master, 256)
            while True:
                i = buf.find(frame.SYNC)
                del buf[:i if i >= 0 else len(buf)]
                if len(buf) < 3 or len(buf) < buf[1] + 8:
                    break
                n, seq = buf[1], buf[2]
                if n <= frame.MAX_PAYLOAD and zlib.crc32(bytes(buf[1:n + 4])) == int.from_bytes(buf[n + 4:n + 8],
                                                                                                  "little"):
                    if buf[3] == MsgType.HELLO:
                        self.hellos += 1
                        os.write(self.master, self.hello_answer(seq)[:-frame.FEC_BYTES])
                    del buf[:n + 8]
                    continue
                body = bytes([1, seq, MsgType.NAK, Status.BAD_CRC])
                crc = zlib.crc32(body)
                os.write(self.master, bytes([frame.SYNC]) + body + crc.to_bytes(4, "little"))
                del buf[:1]


@pytest.fixture(params=[OtherVersionFirmware, Version4Firmware], ids=["newer", "version4"])
def firmware(request):
    """A firmware that reads our frames and answers BAD_VERSION with its own version (a newer one; version 4)."""
    fw = request.param()
    yield fw
    fw.close()


@pytest.fixture
def firmware_v3():
    fw = Version3Firmware()
    yield fw
    fw.close()


def test_harness_names_both_versions_and_the_fix(firmware):
    r = subprocess.run([sys.executable, os.path.join(SRC, "tools", "rbx1-harness"), "--port", firmware.port],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and firmware.hellos >= 1, r.stdout + r.stderr
    want = (f"FAIL  connect: {firmware.port}: the firmware speaks protocol version {firmware.version}, this harness "
            f"{messages.PROTO_VERSION}: flash the matching firmware: make flash PORT={firmware.port} "
            f"(installed: rbx1-flash {firmware.port})")
    assert want in r.stdout.splitlines(), r.stdout


def daemon_link_error(port, tmp_path):
    """Starts rbx1d on port and polls `rbx1 status` until the link reports its error; returns (that error, the
    daemon's stderr after a clean exit)."""
    sock = str(tmp_path / "rbx1d.sock")
    daemon = subprocess.Popen([os.path.join(BIN, "rbx1d"), "--config", os.path.join(SRC, "data", "rbx1.toml"),
                               "--port", port, "--socket", sock, "--console", "127.0.0.1:0",
                               "--state-dir", str(tmp_path / "state")],  # never the machine's /var/lib/rbx1
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        link = {}
        for _ in range(100):  # the daemon's worker opens the link at start and reports why it is not ready
            r = subprocess.run([os.path.join(BIN, "rbx1"), "status", "--json", "--socket", sock],
                               capture_output=True, text=True, timeout=20)
            if r.returncode == 0:
                link = json.loads(r.stdout.strip().splitlines()[-1])["result"]["link"]
                if "error" in link:
                    break
            time.sleep(0.1)
    finally:
        daemon.terminate()
        assert daemon.wait(timeout=10) == 0
    return link.get("error"), daemon.stderr.read()


def test_daemon_names_both_versions_and_the_fix(firmware, tmp_path):
    error, stderr = daemon_link_error(firmware.port, tmp_path)
    want = (f"{firmware.port}: firmware speaks protocol version {firmware.version}, this host "
            f"{messages.PROTO_VERSION}; flash the matching firmware: rbx1-flash {firmware.port} (from a checkout: "
            f"make flash PORT={firmware.port})")
    assert error == want, error
    assert want in stderr


def test_harness_names_version_3_and_the_fix(firmware_v3):
    r = subprocess.run([sys.executable, os.path.join(SRC, "tools", "rbx1-harness"), "--port", firmware_v3.port],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and firmware_v3.hellos >= 1, r.stdout + r.stderr
    port = firmware_v3.port
    want = (f"FAIL  connect: {port}: the firmware speaks protocol version 3 (CRC-16 frames: it NAKs every frame of "
            f"ours), this host {messages.PROTO_VERSION}: flash the matching firmware: make flash PORT={port} "
            f"(installed: rbx1-flash {port})")
    assert want in r.stdout.splitlines(), r.stdout


def test_daemon_names_version_3_and_the_fix(firmware_v3, tmp_path):
    error, stderr = daemon_link_error(firmware_v3.port, tmp_path)
    port = firmware_v3.port
    want = (f"{port}: firmware speaks protocol version 3 (CRC-16 frames: it NAKs every frame of ours), this host "
            f"{messages.PROTO_VERSION}; flash the matching firmware: rbx1-flash {port} (from a checkout: make flash "
            f"PORT={port})")
    assert error == want, error
    assert want in stderr
