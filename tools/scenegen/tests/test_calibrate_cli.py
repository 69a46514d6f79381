"""test_calibrate_cli.py - `rbx1 calibrate` end to end on rendered chessboard views through a known camera, and
its one-line errors (exit 2) on bad input. Skips when build/bin/rbx1 has no calibrate command."""
import json
import os
import subprocess

import cv2
import numpy as np
import pytest

from scenegen import chessboard

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
RBX1 = os.environ.get("RBX1_BIN", os.path.join(ROOT, "build", "bin", "rbx1"))


def _has_calibrate():
    if not os.access(RBX1, os.X_OK):
        return False
    return subprocess.run([RBX1, "calibrate", "--help"], capture_output=True).returncode == 0


BUILT = _has_calibrate()


@pytest.fixture(autouse=True)
def _rbx1_built():
    # `make test` builds rbx1 first: a missing command is a broken build, not a reason to pass.
    if not BUILT:
        pytest.fail(f"{RBX1} with `calibrate` is not built: run make first")

# A tilted table: undistorted pixel -> cm.
H_TRUE = np.array([[0.05, 0.001, -3.0], [0.0005, 0.049, -2.0], [0.00001, 0.00002, 1.0]])


def run(*args):
    return subprocess.run([RBX1, "calibrate", *map(str, args)], capture_output=True, text=True)


@pytest.fixture(scope="module")
def boards(tmp_path_factory):
    d = tmp_path_factory.mktemp("boards")
    for i, v in enumerate(chessboard.render_views(noise=0.8, seed=3)):
        cv2.imwrite(str(d / f"view_{i:02d}.png"), v)
    return d


def table_points(path, cm):
    und = cv2.perspectiveTransform(np.array(cm, float).reshape(-1, 1, 2), np.linalg.inv(H_TRUE)).reshape(-1, 2)
    raw = chessboard.distort_pixels(und)
    with open(path, "w") as f:
        json.dump({"points": [{"px": list(map(float, p)), "cm": list(map(float, c))} for p, c in zip(raw, cm)]}, f)


def test_intrinsics_and_table_homography(boards, tmp_path):
    pts = tmp_path / "points.json"
    table_points(pts, [(1, 1), (20, 1), (20, 16), (1, 16), (10, 8), (5, 12)])
    out = tmp_path / "calib.json"
    p = run("--chessboard", boards, "--board", "9x6", "--square-mm", 20, "--table-points", pts, "--out", out)
    assert p.returncode == 0, p.stderr
    assert "9 of 9 views" in p.stdout
    c = json.load(open(out))
    assert c["format"] == "rbx1-calibration" and c["version"] == 1 and c["image_size"] == [640, 480]
    k = np.array(c["camera_matrix"])
    assert abs(k[0, 0] - 600) < 3 and abs(k[1, 1] - 605) < 3
    assert abs(k[0, 2] - 317.5) < 1.5 and abs(k[1, 2] - 242.25) < 1.5
    assert abs(c["dist_coeffs"][0] - (-0.21)) < 0.02
    # The fitted homography maps an undistorted pixel where the true one does (to 0.01 cm = 0.1 mm).
    h = np.array(c["homography"])
    for px in ((320.0, 240.0), (100.0, 400.0), (600.0, 60.0)):
        a = h @ [px[0], px[1], 1.0]
        b = H_TRUE @ [px[0], px[1], 1.0]
        assert np.allclose(a[:2] / a[2], b[:2] / b[2], atol=0.01)
    # Atomic write: nothing but the output file appeared.
    assert sorted(os.listdir(tmp_path)) == ["calib.json", "points.json"]


def test_px_per_cm_only(tmp_path):
    out = tmp_path / "c.json"
    p = run("--px-per-cm", 40, "--out", out)
    assert p.returncode == 0, p.stderr
    c = json.load(open(out))
    assert c["camera_matrix"] is None and c["dist_coeffs"] is None
    assert np.allclose(c["homography"], [[0.025, 0, 0], [0, 0.025, 0], [0, 0, 1]])


def bad_cases(boards, tmp):
    (tmp / "empty").mkdir()
    (tmp / "junk").mkdir()
    (tmp / "junk" / "a.png").write_bytes(b"not a png at all")
    # A PNG whose data is damaged after a valid header: libpng prints its own "libpng error" line unless muted.
    (tmp / "badpng").mkdir()
    ok, png = cv2.imencode(".png", chessboard.render_views(poses=chessboard.POSES[:1])[0])
    data = bytearray(png.tobytes())
    data[60:400] = b"\x00" * 340
    (tmp / "badpng" / "a.png").write_bytes(bytes(data))
    (tmp / "two").mkdir()
    for i, v in enumerate(chessboard.render_views(poses=chessboard.POSES[:2])):
        cv2.imwrite(str(tmp / "two" / f"v{i}.png"), v)
    (tmp / "bad.json").write_text('{"points": [{"px": [1, 2], "cm": "x"}]}')
    (tmp / "trunc.json").write_text('{"points": [')
    table_points(tmp / "line.json", [(0, 0), (1, 0), (2, 0), (3, 0)])
    out = tmp / "out.json"
    return [
        (["--out", out], "exactly one of --table-points"),
        (["--px-per-cm", 40, "--table-points", tmp / "bad.json", "--out", out], "exactly one of --table-points"),
        (["--px-per-cm", 40], "--out is required"),
        (["--px-per-cm", -1, "--out", out], "exactly one of --table-points"),
        (["--chessboard", tmp / "nope", "--square-mm", 20, "--px-per-cm", 40, "--out", out], "not a folder"),
        (["--chessboard", tmp / "empty", "--square-mm", 20, "--px-per-cm", 40, "--out", out], "no images"),
        (["--chessboard", tmp / "junk", "--square-mm", 20, "--px-per-cm", 40, "--out", out], "not a readable image"),
        (["--chessboard", tmp / "badpng", "--square-mm", 20, "--px-per-cm", 40, "--out", out], "not a readable image"),
        (["--chessboard", tmp / "two", "--square-mm", 20, "--px-per-cm", 40, "--out", out],
         "found in 2 of 2 images"),
        (["--chessboard", boards, "--board", "9by6", "--square-mm", 20, "--px-per-cm", 40, "--out", out],
         "--board must be"),
        (["--chessboard", boards, "--px-per-cm", 40, "--out", out], "--square-mm must be given"),
        (["--table-points", tmp / "bad.json", "--out", out], "points[0].cm must be [x, y]"),
        (["--table-points", tmp / "trunc.json", "--out", out], "not valid JSON"),
        (["--table-points", tmp / "missing.json", "--out", out], "cannot open"),
        (["--table-points", tmp / "line.json", "--out", out], "collinear"),
        (["--px-per-cm", 40, "--out", tmp / "no" / "dir" / "c.json"], "cannot write"),
    ]


def test_bad_input_is_one_line_and_exit_2(boards, tmp_path):
    for args, reason in bad_cases(boards, tmp_path):
        p = run(*args)
        assert p.returncode == 2, (args, p.stdout, p.stderr)
        lines = p.stderr.strip().splitlines()
        assert len(lines) == 1, (args, p.stderr)
        assert reason in lines[0], (args, lines[0])
        assert not (tmp_path / "out.json").exists()
