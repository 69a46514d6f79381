"""test_world_second_look.py - a tall part far off the camera's optical axis (issue 27): the camera sees its side
wall too, and the part scores under what it was taught at (the world bench's false object_absent). Taught once
under the camera, then asked for 70 % of the half view off the axis, it is picked after a second look with the
camera straight over it. An untaught near-twin is not taken, whether the first view left it unknown or took it for
its taught twin (the lean across it): object_absent, nothing placed. Judged by the world's state."""
import pytest

import worldkit

TALL = "c_ring"    # 7.6 mm tall with --class-heights: its wall shows 1 mm off axis
TWIN = ("plate", "plate_long")


def one_part_world(path, seed, cls, along, yaw_deg):
    worldkit.make_world(path, seed, objects=1, errors=(0.0, 0.0, 0.0), classes=cls, class_heights=True)
    worldkit.place_in_view(path, 0, along=along, yaw_deg=yaw_deg)


def taught_library(tmp_path, cls):
    (tmp_path / "teach").mkdir()
    scene = tmp_path / "teach" / "world.json"
    one_part_world(scene, 3000, cls, 0.0, 20.0)
    cell = worldkit.Cell(tmp_path / "teach", scene)
    try:
        library, taught = worldkit.teach_all(cell)
    finally:
        cell.stop()
    assert [t["class"] for t in taught if t["result"]] == [cls], taught
    return library


def off_axis(tmp_path, library, cls, yaw_deg, request):
    """One part of cls 70 % of the half view off the axis; the daemon's events and final line for the request, and
    the world's placements."""
    (tmp_path / "ask").mkdir()
    scene = tmp_path / "ask" / "world.json"
    one_part_world(scene, 3001, cls, 0.7, yaw_deg)
    cell = worldkit.Cell(tmp_path / "ask", scene, library=library)
    try:
        before = len(cell.world.state()["events"])
        events, final = cell.daemon.request(request, timeout=180)
        placed = [e for e in cell.world.state()["events"][before:] if e["event"] == "placement"]
    finally:
        cell.stop()
    return events, final, placed


def pick_off_axis(tmp_path, library, cls, ask, yaw_deg):
    return off_axis(tmp_path, library, cls, yaw_deg, {"cmd": "pick", "name": ask, "place": "tray"})


def named(events, name):
    return [e for e in events if e.get("event") == name]


def test_a_tall_part_off_axis_is_picked_after_a_second_look(tmp_path):
    library = taught_library(tmp_path, TALL)
    events, final, placed = pick_off_axis(tmp_path, library, TALL, TALL, 65.0)
    look, seen = named(events, "second_look"), named(events, "second_look_seen")
    print(look, seen, final)
    # The first view did not name it (that was the false object_absent), the second did, and the world placed it.
    assert TALL not in named(events, "detected")[0]["labels"], events
    assert len(look) == 1 and look[0]["score"] < 0.9, look
    assert seen == [dict(seen[0], name=TALL, seen_as=TALL, taken=True)], seen
    assert "result" in final, final
    assert [(p["class"], p["place"]) for p in placed] == [(TALL, "tray")], placed


@pytest.mark.parametrize("yaw_deg, first", [(0.0, None), (65.0, "plate")])
def test_an_untaught_twin_is_not_taken_after_the_second_look(tmp_path, yaw_deg, first):
    """Turned along the view the first view leaves the untaught plate_long unknown (0.77 as the plate); turned
    across the lean it is taken for the plate (0.998). From straight above it is neither (0.90 < 0.92)."""
    taught, untaught = TWIN
    library = taught_library(tmp_path, taught)
    events, final, placed = pick_off_axis(tmp_path, library, untaught, taught, yaw_deg)
    seen = named(events, "second_look_seen")
    print(named(events, "second_look"), seen, final)
    assert [d["labels"] for d in named(events, "detected")][0] == [first]
    assert len(seen) == 1 and not seen[0]["taken"], seen
    assert final.get("error", {}).get("code") == "object_absent", final
    assert placed == [], placed


def test_a_sort_does_not_take_an_untaught_twin_for_its_taught_one(tmp_path):
    """A sort judges each part from straight above before picking it, as a pick by name does: the untaught
    plate_long, taken for the plate by the first view (turned across the lean), is skipped as not confirmed and
    stays on the table; the sort ends done with nothing picked."""
    taught, untaught = TWIN
    library = taught_library(tmp_path, taught)
    events, final, placed = off_axis(tmp_path, library, untaught, 65.0, {"cmd": "sort", "recipe": {taught: "tray"}})
    seen = named(events, "second_look_seen")
    print(seen, final)
    assert [d["labels"] for d in named(events, "detected")][0] == [taught]
    assert len(seen) == 1 and not seen[0]["taken"], seen
    summary = final["result"]
    assert summary["outcome"] == "done" and summary["picked_total"] == 0 and summary["attempts"] == 0, summary
    assert [(s["class"], s["reason"]) for s in summary["skipped"]] == [(taught, "not_confirmed")], summary
    assert named(events, "skipped")[0]["reason"] == "not_confirmed", events
    assert placed == [], placed
