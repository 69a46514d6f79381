"""test_pick_check.py - the pick check cannot pass on a blind frame (issue 27): with verify_pick, a check frame
that finds no object where the pick's own scan found several is taken again once (a check_blind event each
time); blind twice, the job ends with pick_unverified, never a verified pick. A frame seen on the second try
verifies as before, and a scene of one object whose check finds none is an ordinary verified pick.
The camera is a folder of frames read in name order (one per capture): the demo scene, then the check frames.
The sort judges each pick by its next scan with the same rule (the same function): blind twice ends the sort with
pick_unverified and the pick in the history as unchecked, never picked.
A blind frame here is the empty table itself (no object at all: what a dimmed light or a covered lens gives)."""
import json

import cv2
import numpy as np

import rbx1e2e as e2e
from conftest import fast_config


def erase(img, background, objects):
    """The frame with these truth objects taken away: the table's own pixels over each outline, 8 px wider."""
    mask = np.zeros(img.shape[:2], np.uint8)
    for o in objects:
        cv2.fillPoly(mask, [np.round(np.asarray(o["polygon_px"])).astype(np.int32)], 255)
    mask = cv2.dilate(mask, np.ones((17, 17), np.uint8))
    out = img.copy()
    out[mask > 0] = background[mask > 0]
    return out


def frames(tmp_path, *images):
    d = tmp_path / "frames"
    d.mkdir()
    for i, im in enumerate(images):
        cv2.imwrite(str(d / f"{i:02d}.png"), im)
    return str(d)


def once_labelled(truth):
    """A truth object whose label is the only one of its kind (the daemon picks the better of two alike)."""
    labels = [e2e.truth_label(o) for o in truth["objects"]]
    return next(o for o in truth["objects"] if labels.count(e2e.truth_label(o)) == 1)


def pick(sim, daemon_factory, folder, name):
    cfg = fast_config()
    cfg["camera"]["device"] = folder
    cfg["daemon"].update({"verify_pick": True, "pick_retries": 1})
    d = daemon_factory(sim.port, cfg)
    events, final = d.request({"cmd": "pick", "name": name, "place": "tray"})
    return events, final


def load():
    scene = cv2.imread(str(e2e.DEMO / "scene.png"))
    background = cv2.imread(str(e2e.DEMO / "background.png"))
    return scene, background, e2e.scene_truth()


def test_blind_twice_is_pick_unverified(tmp_path, sim, daemon_factory):
    scene, background, truth = load()
    assert len(truth["objects"]) >= 2
    obj = once_labelled(truth)
    events, final = pick(sim, daemon_factory, frames(tmp_path, scene, background, background), e2e.truth_label(obj))
    assert final.get("error", {}).get("code") == "pick_unverified", final
    blind = e2e.events_named(events, "check_blind")
    assert [e["frame"] for e in blind] == [1, 2], blind
    assert all(e["before"] == len(truth["objects"]) for e in blind), blind
    assert not e2e.events_named(events, "pick_verified")
    assert sim.moves()[-1]["target"] == [0] * 6  # home


def test_blind_once_then_seen_is_verified(tmp_path, sim, daemon_factory):
    scene, background, truth = load()
    obj = once_labelled(truth)
    after = erase(scene, background, [obj])
    events, final = pick(sim, daemon_factory, frames(tmp_path, scene, background, after), e2e.truth_label(obj))
    assert final.get("result", {}).get("verified") is True, final
    assert [e["frame"] for e in e2e.events_named(events, "check_blind")] == [1]
    assert len(e2e.events_named(events, "pick_verified")) == 1


def test_the_last_object_gone_is_verified(tmp_path, sim, daemon_factory):
    # One object in the scan: an empty check frame is what a good pick leaves, not a blind one.
    scene, background, truth = load()
    obj = once_labelled(truth)
    alone = erase(scene, background, [o for o in truth["objects"] if o is not obj])
    events, final = pick(sim, daemon_factory, frames(tmp_path, alone, background), e2e.truth_label(obj))
    assert final.get("result", {}).get("verified") is True, json.dumps(final)
    assert not e2e.events_named(events, "check_blind")


def sort_one(sim, daemon_factory, folder, name):
    """A sort whose recipe maps only `name` (so the pick is that object), then the job's history rows."""
    cfg = fast_config()
    cfg["camera"]["device"] = folder
    cfg["daemon"].update({"pick_retries": 1})
    d = daemon_factory(sim.port, cfg)
    events, final = d.request({"cmd": "sort", "recipe": {name: "tray"}})
    # Read at once: the job's rows are written before its final line, a failed job's too.
    return events, final, d.request({"cmd": "history"})[1]["result"]


def test_sort_blind_twice_is_pick_unverified(tmp_path, sim, daemon_factory):
    scene, background, truth = load()
    obj = once_labelled(truth)
    events, final, hist = sort_one(sim, daemon_factory, frames(tmp_path, scene, background, background),
                                   e2e.truth_label(obj))
    assert final.get("error", {}).get("code") == "pick_unverified", final
    blind = e2e.events_named(events, "check_blind")
    assert [e["frame"] for e in blind] == [1, 2], blind
    assert all(e["before"] == len(truth["objects"]) and e["name"] == e2e.truth_label(obj) for e in blind), blind
    assert not e2e.events_named(events, "pick_verified")
    assert sim.moves()[-1]["target"] == [0] * 6  # home
    assert [p["outcome"] for p in hist["picks"]] == ["unchecked"], hist
    assert [j["outcome"] for j in hist["jobs"]] == ["pick_unverified"], hist["jobs"]


def test_sort_blind_once_then_seen_is_verified(tmp_path, sim, daemon_factory):
    scene, background, truth = load()
    obj = once_labelled(truth)
    after = erase(scene, background, [obj])
    events, final, hist = sort_one(sim, daemon_factory, frames(tmp_path, scene, background, after),
                                   e2e.truth_label(obj))
    assert final.get("result", {}).get("outcome") == "done", final
    assert final["result"]["picked_total"] == 1, final
    assert [e["frame"] for e in e2e.events_named(events, "check_blind")] == [1]
    assert len(e2e.events_named(events, "pick_verified")) == 1
    assert [p["outcome"] for p in hist["picks"]] == ["picked"], hist["picks"]
