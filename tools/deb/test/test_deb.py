"""test_deb.py - the rbx1 Debian package: built by tools/deb/build-deb (`make deb`), checked by lintian (no error;
warnings printed), then installed, used and removed on this machine as root (CI's throwaway machine): files where
they belong, the conffile, the rbx1 user and its groups, the state directory, nothing enabled or started, the
Python client importable, the default URDF valid (check_urdf), the packaged rbx1-flash uploading to the simulated
board, `dpkg -r` keeping the state directory and `dpkg -P` removing it and the client's compiled files. Leaves the
machine as it found it. Env: RBX1_SOURCE_DIR, AVRBOARD."""
import fcntl
import grp
import gzip
import os
import pwd
import re
import subprocess
import time

import pytest

SRC = os.environ.get("RBX1_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", "..", ".."))
AVRBOARD = os.environ.get("AVRBOARD", os.path.join(SRC, "build", "bin", "rbx1-avrboard"))
FILES = ["/usr/bin/rbx1d", "/usr/bin/rbx1", "/usr/bin/rbx1-harness", "/usr/bin/rbx1-flash",
         "/usr/share/rbx1/firmware/rbx1.hex", "/usr/share/rbx1/python/rbx1_harness/cli.py",
         "/usr/share/rbx1/python/rbx1proto/link.py", "/lib/systemd/system/rbx1d.service",
         "/lib/udev/rules.d/99-rbx1.rules", "/etc/rbx1/rbx1.toml", "/usr/share/doc/rbx1/copyright",
         "/usr/share/man/man1/rbx1.1.gz", "/usr/share/man/man8/rbx1d.8.gz", "/usr/share/man/man1/rbx1-flash.1.gz",
         "/usr/share/man/man1/rbx1-harness.1.gz", "/usr/share/rbx1/rbx1.urdf"]
# The Python client library (host/python/rbx1), every module of it, on python3's path.
CLIENT = "/usr/lib/python3/dist-packages/rbx1"
FILES += [f"{CLIENT}/{m}" for m in sorted(os.listdir(os.path.join(SRC, "host", "python", "rbx1"))) if m.endswith(".py")]


def run(*cmd, check=True, **kw):
    r = subprocess.run(list(cmd), capture_output=True, text=True, timeout=kw.pop("timeout", 120), **kw)
    if check:
        assert r.returncode == 0, f"{' '.join(cmd)}: exit {r.returncode}\n{r.stdout}{r.stderr}"
    return r


def dpkg(*args):
    """dpkg, waiting out another package manager's lock (apt in another terminal, tools/install-deps)."""
    for _ in range(60):
        r = run("dpkg", *args, check=False)
        if r.returncode == 0 or "lock" not in r.stderr:
            break
        time.sleep(1)
    assert r.returncode == 0, f"dpkg {' '.join(args)}: exit {r.returncode}\n{r.stdout}{r.stderr}"
    return r


def installed(pkg="rbx1"):
    r = run("dpkg-query", "-W", "-f=${db:Status-Abbrev}", pkg, check=False)
    return r.returncode == 0 and r.stdout.startswith("ii")


def known(db, name):
    try:
        db(name)
        return True
    except KeyError:
        return False


@pytest.fixture(scope="module")
def deb():
    r = run(os.path.join(SRC, "tools", "deb", "build-deb"), timeout=300)
    path = r.stdout.strip().splitlines()[-1]
    arch = run("dpkg", "--print-architecture").stdout.strip()
    assert re.fullmatch(rf".*/build/deb/rbx1_[0-9][^_]*_{arch}\.deb", path), path
    return path


def test_contents_and_dependencies(deb):
    fields = run("dpkg-deb", "-f", deb, "Package", "Architecture", "Depends").stdout
    depends = re.search(r"^Depends: (.*)$", fields, re.M).group(1)
    # dpkg-shlibdeps named Debian's libraries rbx1d links against; the tools the scripts run are listed.
    for lib in ("libopencv-core", "libgpiod2", "libspdlog1", "libc6", "libstdc++6"):
        assert re.search(rf"\b{re.escape(lib)}[\w.-]*", depends), f"no {lib} in Depends: {depends}"
    for tool in ("adduser", "avrdude", "python3", "python3-serial"):
        assert re.search(rf"(^|, ){tool}($|,| )", depends), f"no {tool} in Depends: {depends}"
    listing = run("dpkg-deb", "-c", deb).stdout
    for f in FILES:
        assert f" .{f}\n" in listing, f"{f} not in the package"
    assert "/var/lib/rbx1" not in listing  # made by postinst, owned by the rbx1 user
    for bundled in (".so", "__pycache__", "/usr/local/"):
        assert bundled not in listing, f"{bundled} in the package:\n{listing}"
    conffiles = run("dpkg-deb", "-I", deb, "conffiles").stdout.split()
    assert conffiles == ["/etc/rbx1/rbx1.toml"], conffiles


def test_lintian_reports_no_error_or_warning(deb):
    r = run("lintian", "--tag-display-limit", "0", deb, check=False, timeout=300)
    tags = r.stdout.splitlines()
    errors = [t for t in tags if t.startswith("E:")]
    print("\nlintian: %d errors, %d warnings, %d other tags" % (
        len(errors), sum(t.startswith("W:") for t in tags), sum(not t[:2] in ("E:", "W:") for t in tags)))
    for t in tags:
        print("  " + t)
    assert not errors and r.returncode == 0, r.stdout + r.stderr
    warnings = [t for t in tags if t.startswith("W:")]
    assert not warnings, "\n".join(warnings)


def test_man_pages_say_what_help_says(deb, tmp_path):
    """help2man made them from the programs' --help: every option rbx1d and rbx1 print, and each rbx1 command."""
    run("dpkg-deb", "-x", deb, str(tmp_path))
    for page, exe in (("man8/rbx1d.8.gz", "rbx1d"), ("man1/rbx1.1.gz", "rbx1")):
        with gzip.open(tmp_path / "usr" / "share" / "man" / page, "rt") as f:
            text = f.read()
        shown = run(os.path.join(SRC, "build", "bin", exe), "--help").stdout
        for option in set(re.findall(r"(?<![\w-])--[a-z][a-z-]+", shown)):
            assert option.replace("-", "\\-") in text, f"{option} of {exe} --help not in {page}"
        if exe == "rbx1":
            for command in re.findall(r"^  ([a-z][a-z-]*)  ", shown.split("Subcommands:")[1], re.M):
                assert f".SS {command}\n" in text, f"rbx1 {command} not in {page}"


def test_urdf_is_the_default_arms_and_valid(deb, tmp_path):
    """The packaged URDF is what rbx1 urdf prints for the bundled config, and Debian's check_urdf accepts it."""
    run("dpkg-deb", "-x", deb, str(tmp_path))
    urdf = tmp_path / "usr" / "share" / "rbx1" / "rbx1.urdf"
    here = run(os.path.join(SRC, "build", "bin", "rbx1"), "urdf", "--config", os.path.join(SRC, "data", "rbx1.toml"))
    assert urdf.read_text() == here.stdout
    r = run("check_urdf", str(urdf))
    assert "robot name is: rbx1\n" in r.stdout and "root Link: base_link" in r.stdout, r.stdout


@pytest.fixture
def machine():
    """Root only; refuses to touch a machine where the package or its paths already are; restores users, groups
    and paths the install created."""
    if os.geteuid() != 0:
        pytest.skip("installing the package needs root (dpkg -i); CI runs make test as root on a throwaway machine")
    lock = open("/run/lock/rbx1-deb-test.lock", "w")  # one install test per machine, whichever checkout runs it
    fcntl.flock(lock, fcntl.LOCK_EX)
    assert not installed(), "rbx1 is installed on this machine: the test would replace it (dpkg -P rbx1 first)"
    for path in ("/etc/rbx1", "/var/lib/rbx1"):
        assert not os.path.exists(path), f"{path} exists: the test would purge it"
    before = {"user": known(pwd.getpwnam, "rbx1"), "rbx1": known(grp.getgrnam, "rbx1"),
              "gpio": known(grp.getgrnam, "gpio")}
    yield
    if run("dpkg-query", "-W", "rbx1", check=False).returncode == 0:
        dpkg("--purge", "rbx1")
    if not before["user"] and known(pwd.getpwnam, "rbx1"):
        run("deluser", "--system", "--quiet", "rbx1", check=False)
    if not before["rbx1"] and known(grp.getgrnam, "rbx1"):
        run("delgroup", "--system", "--quiet", "rbx1", check=False)
    if not before["gpio"] and known(grp.getgrnam, "gpio"):
        run("delgroup", "--system", "--quiet", "gpio", check=False)
    lock.close()


def test_install_flash_remove_purge(deb, machine, tmp_path):
    dpkg("-i", deb)
    assert installed()
    for f in FILES:
        assert os.path.isfile(f), f"{f} missing after dpkg -i"
    with open(os.path.join(SRC, "build", "firmware", "rbx1.hex")) as a, open("/usr/share/rbx1/firmware/rbx1.hex") as b:
        assert a.read() == b.read()

    user = pwd.getpwnam("rbx1")
    assert user.pw_uid < 1000 and user.pw_dir == "/var/lib/rbx1" and grp.getgrgid(user.pw_gid).gr_name == "rbx1"
    groups = {g.gr_name for g in grp.getgrall() if "rbx1" in g.gr_mem}
    assert {"dialout", "video", "gpio"} <= groups, groups
    st = os.stat("/var/lib/rbx1")
    assert st.st_uid == user.pw_uid and st.st_gid == user.pw_gid

    # Installed, neither enabled nor started.
    assert not os.path.lexists("/etc/systemd/system/multi-user.target.wants/rbx1d.service")
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            assert os.readlink(f"/proc/{pid}/exe") != "/usr/bin/rbx1d", "rbx1d runs after dpkg -i"
        except OSError:
            pass
    unit = open("/lib/systemd/system/rbx1d.service").read()
    assert "ExecStart=/usr/bin/rbx1d --config /etc/rbx1/rbx1.toml\n" in unit

    # The installed programs run against the installed files.
    # Syntax only: the installed config names this machine's camera and a library the operator teaches later.
    assert run("/usr/bin/rbx1d", "--config", "/etc/rbx1/rbx1.toml", "--check-syntax").stdout == "OK\n"
    assert "handshake" in run("/usr/bin/rbx1-harness", "--list").stdout
    assert run("/usr/bin/rbx1", "--help").returncode == 0
    # The Python client imports from python3's path alone (not this checkout's host/python), byte-compiled.
    script = "import rbx1; print(rbx1.__file__, rbx1.Arm.__name__, rbx1.ObjectAbsent.__name__)"
    r = run("/usr/bin/python3", "-c", script, cwd=str(tmp_path), env={"PATH": "/usr/bin:/bin"})
    assert r.stdout.split() == [f"{CLIENT}/__init__.py", "Arm", "ObjectAbsent"], r.stdout
    r = run("/usr/bin/rbx1-flash", check=False)
    assert r.returncode == 2 and r.stderr.startswith("usage: rbx1-flash PORT"), r.stderr

    # rbx1-flash uploads the packaged image to the simulated board through its bootloader.
    # The board outlives the upload's own deadline; its log (resets, boot events) goes with a failure.
    log = tmp_path / "board.log"
    with open(log, "w") as err:
        board = subprocess.Popen([AVRBOARD, "--flash", str(tmp_path / "flash.bin"), "--max-seconds", "200"],
                                 stdout=subprocess.PIPE, stderr=err, text=True)
    try:
        port = board.stdout.readline().strip()
        r = run("/usr/bin/rbx1-flash", port, check=False, timeout=150)
        assert r.returncode == 0 and "bytes of flash verified" in r.stderr, r.stderr + "\nthe board's log:\n" + log.read_text()
    finally:
        board.terminate()
        board.wait(10)

    # The operator's state survives removal; the conffile too. Purge removes both.
    with open("/var/lib/rbx1/library.json", "w") as f:
        f.write("{}\n")
    dpkg("-r", "rbx1")
    assert not os.path.exists("/usr/bin/rbx1d")
    assert os.path.isfile("/var/lib/rbx1/library.json") and os.path.isfile("/etc/rbx1/rbx1.toml")
    dpkg("-P", "rbx1")
    assert not os.path.exists("/var/lib/rbx1") and not os.path.exists("/etc/rbx1")
    assert not os.path.exists(CLIENT), os.listdir(CLIENT)  # no byte-compiled file left behind
    assert run("dpkg-query", "-W", "rbx1", check=False).returncode != 0
