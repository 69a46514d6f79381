"""test_urdf.py - `rbx1 urdf` read by Debian's check_urdf (liburdfdom-tools): the default arm, another config's
arm, and a broken description that it must reject (so the check can fail)."""
import shutil
import subprocess

import pytest

import rbx1e2e as e2e

CHECK_URDF = shutil.which("check_urdf") or "/usr/bin/check_urdf"


def rbx1_urdf(*args):
    r = subprocess.run([e2e.need(e2e.BIN / "rbx1"), "urdf", *args], capture_output=True, text=True, timeout=30)
    assert r.returncode == 0, r.stderr
    return r.stdout


def check_urdf(tmp_path, text):
    path = tmp_path / "rbx1.urdf"
    path.write_text(text)
    return subprocess.run([e2e.need(CHECK_URDF), str(path)], capture_output=True, text=True, timeout=30)


def test_default_arm_passes_check_urdf(tmp_path):
    r = check_urdf(tmp_path, rbx1_urdf())
    assert r.returncode == 0, r.stdout + r.stderr
    assert "robot name is: rbx1" in r.stdout
    assert "root Link: base_link" in r.stdout
    # The whole tree: six revolute links, the gripper, tool0 and the camera under the last link.
    for link in ["link_1", "link_2", "link_3", "link_4", "link_5", "link_6", "tool0", "camera_optical",
                 "finger_left", "finger_right"]:
        assert link in r.stdout


def test_configured_arm_passes_and_differs(tmp_path):
    cfg = {"arm": {"links": {"base_height_mm": 300.0, "upper_arm_mm": 180.0, "forearm_mm": 250.0, "tool_mm": 90.0},
                   "joints": {"j2": {"min_deg": -80.0}}}}
    path = e2e.write_config(tmp_path, cfg)
    text = rbx1_urdf("--config", str(path))
    assert text != rbx1_urdf()
    assert 'xyz="0 0 0.3"' in text and 'xyz="0 0 0.18"' in text and 'xyz="0 0 0.25"' in text
    assert 'lower="-1.396263401595' in text  # -80 deg in radians
    r = check_urdf(tmp_path, text)
    assert r.returncode == 0, r.stdout + r.stderr


def test_bad_config_names_the_key(tmp_path):
    path = e2e.write_config(tmp_path, {"arm": {"links": {"upper_arm_mm": -5.0}}})
    r = subprocess.run([e2e.need(e2e.BIN / "rbx1"), "urdf", "--config", str(path)], capture_output=True, text=True)
    assert r.returncode == 2
    assert "arm.links.upper_arm_mm" in r.stderr


def test_check_urdf_rejects_a_broken_description(tmp_path):
    broken = rbx1_urdf().replace('<child link="link_3"/>', '<child link="no_such_link"/>')
    assert check_urdf(tmp_path, broken).returncode != 0
