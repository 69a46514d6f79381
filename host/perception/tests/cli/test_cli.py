"""test_cli.py - rbx1 detect/teach/plot through the real binary: JSON contract, report, files, and bad input
(unreadable, corrupt, empty, huge images, wrong-size background, corrupt library or calibration, all-foreground):
one clear line on stderr and exit 2."""
import json
import os
import re
import struct
import subprocess
import zlib

import cv2
import numpy as np
import pytest

RBX1 = os.environ.get("RBX1_BIN", os.path.join(os.path.dirname(__file__), "../../../../build/bin/rbx1"))


def run(*args):
    return subprocess.run([RBX1, *map(str, args)], capture_output=True, text=True, timeout=60)


def scene(path, shapes, bg=200, fg=60, size=(480, 640)):
    img = np.full(size + (3,), bg, np.uint8)
    for kind, *p in shapes:
        if kind == "rect":
            (cx, cy), (w, h), a = p
            box = np.round(cv2.boxPoints(((cx, cy), (w, h), a)) * 16).astype(np.int32)
            cv2.fillPoly(img, [box], (fg, fg, fg), cv2.LINE_AA, shift=4)
        else:
            (cx, cy), (ax, ay), a = p
            cv2.ellipse(img, (cx, cy), (ax, ay), a, 0, 360, (fg, fg, fg), -1, cv2.LINE_AA)
    cv2.imwrite(str(path), img)
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    f = {
        "two": scene(d / "two.png", [("rect", (200, 150), (120, 40), 30), ("ell", (450, 320), (50, 25), -20)]),
        "bar": scene(d / "bar.png", [("rect", (320, 240), (120, 40), 0)]),
        "empty_scene": scene(d / "empty_scene.png", []),
        "small_bg": scene(d / "small_bg.png", [], size=(100, 100)),
        "dark": scene(d / "dark.png", [], bg=20),
    }
    (d / "empty.png").write_bytes(b"")
    f["empty"] = d / "empty.png"
    (d / "corrupt.png").write_bytes(b"\x89PNG\r\n\x1a\n" + os.urandom(200))
    f["corrupt"] = d / "corrupt.png"
    # A valid PNG header claiming 100000 x 100000 pixels.
    ihdr = struct.pack(">IIBBBBB", 100000, 100000, 8, 0, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    png = b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + chunk + struct.pack(">I", zlib.crc32(chunk))
    (d / "huge.png").write_bytes(png)
    f["huge"] = d / "huge.png"
    (d / "notjson.json").write_text("{ this is not json")
    f["badlib"] = d / "notjson.json"
    (d / "badcal.json").write_text("[1, 2, 3]")
    f["badcal"] = d / "badcal.json"
    # The same scene as a JPEG cut in half: libjpeg would fill the missing rows with grey and say nothing.
    ok, jpg = cv2.imencode(".jpg", cv2.imread(str(f["two"])))
    (d / "truncated.jpg").write_bytes(jpg.tobytes()[:len(jpg) // 2])
    f["truncated_jpg"] = d / "truncated.jpg"
    png = f["two"].read_bytes()
    (d / "truncated.png").write_bytes(png[:len(png) - 40])
    f["truncated_png"] = d / "truncated.png"
    f["dir"] = d
    return f


def test_detect_json_contract(files):
    r = run("detect", files["two"], "--json", "--px-per-cm", 20)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert doc["image"] == {"width": 640, "height": 480}
    assert doc["px_per_cm"] == 20.0
    assert [o["index"] for o in doc["objects"]] == [1, 2]
    o = doc["objects"][0]
    assert set(o) == {"index", "label", "match_score", "centroid_px", "centroid_cm", "area_px", "edge_points",
                      "orientation_deg", "axis_line", "elongation", "elongated", "grip", "touching", "identification"}
    assert o["identification"] is None  # no library
    assert set(o["grip"]) == {"p1_px", "p2_px", "opening_px", "opening_cm", "angle_deg", "feasible", "reason"}
    assert o["touching"] is False
    assert o["grip"]["feasible"] is True and o["grip"]["reason"] is None
    assert o["label"] is None and o["match_score"] is None
    assert abs(o["centroid_px"][0] - 200) < 0.6 and abs(o["centroid_px"][1] - 150) < 0.6
    assert abs(o["centroid_cm"][0] - 10) < 0.05
    assert abs(o["orientation_deg"] - 30) < 0.5
    assert abs(o["axis_line"]["slope"] - 0.5774) < 0.01
    assert abs(o["grip"]["opening_px"] - 40) < 1.5
    assert abs(o["grip"]["angle_deg"] + 60) < 1.5


def test_detect_report_and_annotation(files):
    out = files["dir"] / "ann.png"
    r = run("detect", files["two"], "--px-per-cm", 20, "--annotate", out)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert lines[0] == "Data for object #1"
    assert lines[1].startswith("Centre at ") and lines[1].endswith(" cm")
    x, y = (float(v.split()[0]) for v in lines[1][len("Centre at "):].split(", "))
    assert abs(x - 10) < 0.05 and abs(y - 7.5) < 0.05
    assert lines[2].startswith("Gripper opening = 2.0")
    assert "degrees w.r.t. robotic arm horizontal reference axis." in lines[3]
    img = cv2.imread(str(out))
    assert img is not None and img.shape == (480, 640, 3)


def test_teach_then_identify(files):
    lib = files["dir"] / "lib.json"
    r = run("teach", files["bar"], "--name", "bar", "--library", lib)
    assert r.returncode == 0, r.stderr
    r = run("detect", files["two"], "--json", "--library", lib)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert doc["objects"][0]["label"] == "bar" and doc["objects"][0]["match_score"] > 0.5
    assert doc["objects"][1]["label"] is None
    assert json.loads(lib.read_text())["objects"][0]["name"] == "bar"


def test_untaught_twin_stays_unknown(files):
    """Issue 27: with one of two near-twin bars taught, the other (10 % longer) is unknown, not the taught one,
    although it scores over today's global 0.5; the taught bar itself is known at other poses."""
    d = files["dir"]
    lib = d / "twin-lib.json"
    r = run("teach", files["bar"], "--name", "bar", "--library", lib)
    assert r.returncode == 0 and "accepted from" in r.stdout, r.stderr
    threshold = json.loads(lib.read_text())["objects"][0]["threshold"]
    assert 0.5 < threshold < 1
    for k, angle in enumerate((35, 100, -62)):
        twin = scene(d / f"twin{k}.png", [("rect", (300 + 7 * k, 220), (132, 40), angle)])
        o = json.loads(run("detect", twin, "--json", "--library", lib).stdout)["objects"][0]
        ident = o["identification"]
        assert o["label"] is None and o["match_score"] is None, (angle, ident)
        assert ident["verdict"] == "below_threshold" and ident["best"] == "bar", ident
        assert 0.5 <= ident["best_score"] < ident["threshold"] == threshold, ident  # today's rule: a "bar"
        assert ident["runner_up"] is None and ident["margin"] is None  # one entry
        same = scene(d / f"same{k}.png", [("rect", (300 + 7 * k, 220), (120, 40), angle)])
        o = json.loads(run("detect", same, "--json", "--library", lib).stdout)["objects"][0]
        assert o["label"] == "bar" and o["identification"]["verdict"] == "known", (angle, o["identification"])
    r = run("detect", d / "twin0.png", "--library", lib)
    assert "Identified as unknown (below_threshold: nearest bar, match 0." in r.stdout, r.stdout


def test_teaching_a_second_name_for_a_known_object_warns(files):
    """Issue 27: the same bar taught again as "rod" (turned, moved) makes twins: taught, with a warning naming the
    entry, the score and what follows; a different object (an ellipse) taught beside them is not warned about."""
    d = files["dir"]
    lib = d / "second-name-lib.json"
    assert run("teach", files["bar"], "--name", "bar", "--library", lib).returncode == 0
    turned = scene(d / "bar-turned.png", [("rect", (280, 260), (120, 40), 37)])
    r = run("teach", turned, "--name", "rod", "--library", lib)
    assert r.returncode == 0, r.stderr
    warn = [line for line in r.stderr.splitlines() if line.startswith("rbx1 teach: warning: ")]
    assert len(warn) == 1, r.stderr
    m = re.search(r'"rod" looks like "bar" already in the library \(match ([0-9.]+), threshold ([0-9.]+)\)', warn[0])
    assert m and float(m[1]) >= float(m[2]) > 0.5, warn
    assert 'picks by "rod" and "bar" will answer unknown (ambiguous) for both' in warn[0], warn
    assert [o["name"] for o in json.loads(lib.read_text())["objects"]] == ["bar", "rod"]  # taught anyway
    # Both taught: the bar is ambiguous between them, as the warning said.
    o = json.loads(run("detect", files["bar"], "--json", "--library", lib).stdout)["objects"][0]
    assert o["label"] is None and o["identification"]["verdict"] == "ambiguous", o["identification"]
    oval = scene(d / "oval.png", [("ell", (300, 240), (70, 30), 15)])
    r = run("teach", oval, "--name", "oval", "--library", lib)
    assert r.returncode == 0 and "warning" not in r.stderr, r.stderr
    # Taught again under its own name: replaced, not a twin of itself.
    r = run("teach", turned, "--name", "rod", "--library", lib)
    assert r.returncode == 0 and r.stderr.count("warning") == 1 and '"bar"' in r.stderr, r.stderr


def test_teach_needs_exactly_one_object(files):
    r = run("teach", files["two"], "--name", "x", "--library", files["dir"] / "lib2.json")
    assert r.returncode == 2
    assert "exactly one object, found 2" in r.stderr
    assert not (files["dir"] / "lib2.json").exists()


def test_plot_writes_three_pngs(files):
    out = files["dir"] / "plots"
    r = run("plot", files["two"], "--object", 2, "--out-dir", out)
    assert r.returncode == 0, r.stderr
    for name in ("profile", "profile-ref", "opening"):
        assert cv2.imread(str(out / f"object-2-{name}.png")) is not None


def test_zero_objects_is_success(files):
    r = run("detect", files["empty_scene"], "--json")
    assert r.returncode == 0
    assert json.loads(r.stdout)["objects"] == []


@pytest.mark.parametrize("case,args,message", [
    ("missing", ["detect", "/nonexistent/x.png"], "cannot be read"),
    ("empty", ["detect", "{empty}"], "empty"),
    ("corrupt", ["detect", "{corrupt}"], "not a readable image"),
    ("truncated jpeg", ["detect", "{truncated_jpg}"], "truncated"),
    ("truncated png", ["detect", "{truncated_png}"], "truncated"),
    ("folder", ["detect", "{dir}"], "is a folder, not an image file"),
    ("zero scale", ["detect", "{two}", "--px-per-cm", "0"], "must be greater than 0, got 0"),
    ("negative gripper", ["detect", "{two}", "--gripper-max-cm", "-1"], "must be greater than 0, got -1"),
    ("huge", ["detect", "{huge}"], "too large"),
    ("bg size", ["detect", "{two}", "--background", "{small_bg}"], "background is 100x100 but the frame is 640x480"),
    ("bad lib", ["detect", "{two}", "--library", "{badlib}"], "invalid JSON"),
    ("bad cal", ["detect", "{two}", "--calibration", "{badcal}"], "badcal.json"),
    ("all fg", ["detect", "{dark}", "--background", "{empty_scene}"], "foreground"),
    ("bad polarity", ["detect", "{two}", "--objects", "grey"], "--objects"),
    ("both scales", ["detect", "{two}", "--px-per-cm", "10", "--calibration", "{badcal}"], "excludes"),
    ("teach bad lib", ["teach", "{bar}", "--name", "b", "--library", "{badlib}"], "invalid JSON"),
    ("plot no object", ["plot", "{two}", "--object", "5", "--out-dir", "{dir}"], "no object #5"),
])
def test_bad_input_exits_2_with_one_line(files, case, args, message):
    args = [a.format(**{k: str(v) for k, v in files.items()}) for a in args]
    r = run(*args)
    assert r.returncode == 2, (case, r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, (case, r.stderr)
    assert message in lines[0], (case, lines[0])
    assert r.stdout == ""


def test_zero_scale_message_is_short(files):
    r = run("detect", files["two"], "--px-per-cm", "0")
    assert r.returncode == 2 and len(r.stderr) < 200, r.stderr


def test_ten_bit_png_keeps_its_contrast(files, tmp_path):
    # A 10-bit sensor image in a 16-bit PNG (0..1023): scaled as 16-bit data it would be nearly black.
    img8 = cv2.imread(str(files["two"]), cv2.IMREAD_GRAYSCALE).astype(np.uint16)
    path = tmp_path / "ten_bit.png"
    cv2.imwrite(str(path), img8 * 4)
    r = run("detect", path, "--json")
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert len(doc["objects"]) == 2
    ref = json.loads(run("detect", files["two"], "--json").stdout)
    for a, b in zip(doc["objects"], ref["objects"]):
        assert abs(a["centroid_px"][0] - b["centroid_px"][0]) < 0.1
        assert abs(a["orientation_deg"] - b["orientation_deg"]) < 0.2
