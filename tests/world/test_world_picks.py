"""test_world_picks.py - the closed loop: rbx1d picks objects of generated worlds through rbx1-world's camera and
rbx1-simfw, and success is the world's state (the object resting in the place asked for), not the plan.

With the issue's full errors (camera mount +-5 mm / +-3 deg, links +-1 mm, lens distortion, light drift) the
operator first calibrates the workspace (issue 11) in the world: the marker sheet on the table, each marker touched
by jogging and recorded, the fit saved; then every pick must land. Without that calibration the daemon's camera
mapping is the nominal one and the picks miss by the mount error: that test checks that the daemon's own check
tells the truth about each pick (pick_failed exactly when the world did not place the object). A third runs with
link-length errors, distortion and light drift but an exact camera mount and no calibration."""
import pytest

import worldkit

# Convex objects: the paper's grip (the shortest chord through the centroid) leaves room for 10 mm fingers.
# The star and the L are left out on purpose: a finger lands on their own points/arm (tools/world/README.md).
CONVEX = "rectangle,ellipse,triangle"


def run(tmp_path, seed, objects, errors, classes=CONVEX, calibrate=False):
    scene_path = tmp_path / "world.json"
    worldkit.make_world(scene_path, seed, objects=objects, errors=errors, classes=classes)
    cell = worldkit.Cell(tmp_path, scene_path)
    try:
        records = []
        if calibrate:
            records.append(cell.calibrate_workspace())
        for i, obj in enumerate(cell.scene["objects"]):
            place = "tray" if i % 2 == 0 else "bin"
            before = len(cell.world.state()["events"])
            events, final, _ = cell.pick(obj["class"], place)
            new = cell.world.state()["events"][before:]
            records.append({"label": obj["class"], "place": place, "final": final, "events": events,
                            "world": new})
        return records, cell.world.state()
    finally:
        cell.stop()


def names(events):
    return [e.get("event") for e in events]


@pytest.mark.parametrize("seed", [31, 32])
def test_picks_land_in_place_under_full_errors_after_the_workspace_calibration(tmp_path, seed):
    (fit, *records), state = run(tmp_path, seed=seed, objects=4, errors=(1.0, 5.0, 3.0), calibrate=True)
    e = state["errors"]
    print(f"\nworld {seed}: mount {[round(v, 2) for v in e['mount_xyz_mm']]} mm "
          f"{[round(v, 2) for v in e['mount_rpy_deg']]} deg, links {[round(v, 2) for v in e['links_mm']]} mm; "
          f"calibration over markers {fit['seen']} ({fit['jogs']} jogs): RMS {fit['rms_mm']} mm, worst "
          f"leave-one-out {fit['max_loo_mm']} mm, table at z {fit['table_z_mm']} mm (spread {fit['table_z_spread_mm']} mm)")
    assert max(abs(v) for v in e["mount_rpy_deg"]) > 1.0, e  # the errors are really there
    assert fit["seen"] == [0, 1, 2, 3, 4, 5] and fit["accepted"] and fit["saved"], fit
    assert fit["rms_mm"] < 0.5 and fit["max_loo_mm"] < 1.0, fit
    for r in records:
        assert "result" in r["final"], (r["label"], r["final"], r["world"])
        assert r["final"]["result"]["verified"] is True and r["final"]["result"]["attempts"] == 1
        planned = [ev for ev in r["events"] if ev.get("event") == "planned"]
        assert planned[0]["map"] == "workspace", planned[0]
        assert [ev["event"] for ev in r["world"]] == ["grasp", "placement"], r["world"]
        grasp, placement = r["world"]
        print(f"  {r['label']} -> {r['place']}: grasp offset {grasp['offset_mm']} mm, yaw error "
              f"{grasp['yaw_error_deg']} deg, placement error {placement['error_mm']} mm")
        assert grasp["offset_mm"] < 2.0 and grasp["yaw_error_deg"] < 5.0, grasp
        # The table measured by the touches: the fingertips stop above the real table, not in it.
        assert 0.5 < grasp["tool_mm"][2] < 4.0, grasp
        assert placement["place"] == r["place"] and placement["error_mm"] < 3.0, placement
    assert worldkit.placed_correctly(state, records) == len(records) == 4
    # Nothing hit during the calibration's touches either (the events include them).
    assert state["counts"]["collisions"] == 0 and state["counts"]["closed_empty"] == 0, state["counts"]


def test_picks_land_in_place_with_link_errors_lens_and_light_drift(tmp_path):
    records, state = run(tmp_path, seed=21, objects=4, errors=(1.0, 0.0, 0.0))
    assert any(abs(e) > 0.1 for e in state["errors"]["links_mm"]), state["errors"]
    for r in records:
        assert "result" in r["final"], (r["label"], r["final"], r["world"])
        assert r["final"]["result"]["verified"] is True and r["final"]["result"]["attempts"] == 1
        assert "pick_failed" not in names(r["events"]), r["events"]
        assert [e["event"] for e in r["world"]] == ["grasp", "placement"], r["world"]
        grasp, placement = r["world"]
        assert grasp["offset_mm"] < 2.0 and grasp["yaw_error_deg"] < 5.0, grasp
        assert placement["place"] == r["place"] and placement["error_mm"] < 3.0, placement
    assert worldkit.placed_correctly(state, records) == len(records) == 4
    assert state["counts"]["collisions"] == 0 and state["counts"]["closed_empty"] == 0, state["counts"]


def test_the_pick_check_tells_the_truth_under_full_errors_without_calibration(tmp_path):
    records, state = run(tmp_path, seed=22, objects=3, errors=(1.0, 5.0, 3.0))
    report = []
    for r in records:
        placed = [e for e in r["world"] if e["event"] == "placement"]
        failed = [e for e in r["events"] if e.get("event") == "pick_failed"]
        attempts = names(r["events"]).count("planned")
        report.append(f"{r['label']}: attempts {attempts}, placed {len(placed)}, pick_failed {len(failed)}, "
                      f"world {[e['event'] for e in r['world']]}")
        if "result" in r["final"]:
            # Verified: the world placed it where asked, and every earlier attempt reported as failed really was.
            assert placed and placed[-1]["place"] == r["place"], report[-1]
            assert len(failed) == attempts - 1, report[-1]
        else:
            # pick_failed: the world never placed it, each attempt was reported, the last one without a retry.
            assert r["final"]["error"]["code"] == "pick_failed", r["final"]
            assert not placed, report[-1]
            assert len(failed) == attempts == 2, report[-1]
            assert [f["retry"] for f in failed] == [True, False]
            assert all(f["reason"] == "still_there" for f in failed)
    print("\n".join(report))
