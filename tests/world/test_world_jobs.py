"""test_world_jobs.py - the cell's jobs in the simulated world: a recipe saved, a sort and then a clear run to their
end, judged by the world's state (each object resting in the place its class maps to, or on the table when the
recipe leaves it there; no collision); the history read back by the CLI; and rbx1d killed with SIGKILL mid-job:
every committed row survives, no half row, the job shown as interrupted after the restart."""
import json
import os
import signal
import sqlite3
import subprocess
import time

import pytest

import worldkit
from worldkit import e2e

CONVEX = "rectangle,ellipse,triangle"


def cell_for(tmp_path, seed, objects):
    scene_path = tmp_path / "world.json"
    worldkit.make_world(scene_path, seed, objects=objects, errors=(1.0, 0.0, 0.0), classes=CONVEX)
    return worldkit.Cell(tmp_path, scene_path)


def cli(cell, *args):
    return subprocess.run([str(e2e.BIN / "rbx1"), *args, "--socket", cell.daemon.socket], capture_output=True,
                          text=True, timeout=300)


def test_sort_then_clear_run_to_their_end_and_the_world_agrees(tmp_path):
    cell = cell_for(tmp_path, seed=21, objects=4)
    try:
        classes = sorted({o["class"] for o in cell.scene["objects"]})
        assert len(classes) >= 2, classes
        # The recipe maps all but one class: that one stays on the table for the clear.
        recipe = {c: ("tray" if i % 2 == 0 else "bin") for i, c in enumerate(classes[:-1])}
        _, bad = cell.daemon.request({"cmd": "recipe_save", "name": "bins", "recipe": {classes[0]: "shelf"}})
        assert bad["error"]["code"] == "bad_recipe" and '"shelf"' in bad["error"]["message"], bad
        (tmp_path / "bins.json").write_text(json.dumps(recipe))
        saved = cli(cell, "recipe", "save", "bins", str(tmp_path / "bins.json"))
        assert saved.returncode == 0, saved.stderr
        listed = cli(cell, "recipes", "--json")
        assert listed.returncode == 0, listed.stderr
        book = json.loads(listed.stdout.splitlines()[-1])["result"]
        assert book["recipes"] == {"bins": recipe} and book["file"].endswith("/recipes.json"), book
        assert set(classes) <= set(book["classes"]) and {"tray", "bin"} <= set(book["places"]), book

        t0 = time.monotonic()
        sort = cli(cell, "sort", "--recipe", "bins", "--json")
        sort_s = time.monotonic() - t0
        assert sort.returncode == 0, sort.stdout[-3000:] + sort.stderr
        lines = [json.loads(line) for line in sort.stdout.splitlines()]
        summary = lines[-1]["result"]
        mapped = [o for o in cell.scene["objects"] if o["class"] in recipe]
        assert summary["outcome"] == "done" and summary["picked_total"] == len(mapped), summary
        assert summary["left"] == {classes[-1]: sum(o["class"] == classes[-1] for o in cell.scene["objects"])}
        assert summary["skipped"] == [], summary
        state = cell.world.state()
        for o in state["objects"]:
            want = recipe.get(o["class"])
            assert o["place"] == want and not o["held"], (o, recipe)
        # No homing between picks: the only move home is the last one.
        homes = [e for e in lines[:-1] if e.get("event") == "step" and e.get("name") == "home"]
        assert len(homes) == 1, homes

        clear = cell.ok({"cmd": "clear", "place": "bin"})
        assert clear["outcome"] == "done" and clear["picked_total"] == len(cell.scene["objects"]) - len(mapped)
        state = cell.world.state()
        for o in state["objects"]:
            assert o["place"] == recipe.get(o["class"], "bin") and not o["held"], o
        assert state["counts"]["collisions"] == 0 and state["counts"]["closed_empty"] == 0, state["counts"]

        hist = json.loads(cli(cell, "history", "--json").stdout)
        assert [j["kind"] for j in hist["jobs"]] == ["clear", "sort"]
        assert [j["outcome"] for j in hist["jobs"]] == ["done", "done"]
        picked = [p for p in hist["picks"] if p["outcome"] == "picked"]
        assert len(picked) == len(cell.scene["objects"]), hist["picks"]
        assert all(p["scan"] and p["image"] and p["grip_opening_cm"] > 0 and p["cycle_ms"] > 0 for p in picked)
        csv = cli(cell, "history", "--csv", "--job", str(hist["jobs"][1]["id"])).stdout.splitlines()
        assert csv[0].startswith("id,job,ts,class,") and len(csv) == 1 + len(mapped), csv
        print(f"\nsort of {len(mapped)} objects: {sort_s:.1f} s wall, {summary['picks_per_min']} picks/min "
              f"(elapsed {summary['elapsed_s']} s); clear of {clear['picked_total']}: {clear['elapsed_s']} s")
    finally:
        cell.stop()


class Killing(Exception):
    """Raised from the event callback to stop reading: the daemon is about to be killed."""


def test_history_survives_a_kill_mid_job(tmp_path):
    cell = cell_for(tmp_path, seed=23, objects=3)
    try:
        verified, control = [], []

        def on_event(ev):
            # After the first pick: pause (the job holds at the scan pose), resume, and kill rbx1d as the next
            # pick's motion starts.
            name = ev.get("event")
            if name == "pick_verified":
                verified.append(ev)
                if len(verified) == 1:  # the pause may reach the job during the next pick: it finishes that first
                    control.append(cell.daemon.request({"cmd": "pause"})[1])
            elif name == "paused":
                assert cell.daemon.request({"cmd": "status"})[1]["result"]["job"] == "clear"
                control.append(cell.daemon.request({"cmd": "resume"})[1])
            elif name == "resumed":
                control.append(name)
            elif name == "planned" and "resumed" in control:
                raise Killing

        with pytest.raises(Killing):
            cell.daemon.request({"cmd": "clear", "place": "tray"}, timeout=300, on_event=on_event)
        assert [c if isinstance(c, str) else list(c) for c in control] == [["result"], ["result"], "resumed"], control
        time.sleep(0.3)  # into the move
        cell.daemon.proc.send_signal(signal.SIGKILL)
        cell.daemon.proc.wait()
        cell.daemon.log.close()

        db = tmp_path / "state" / "history.sqlite"
        con = sqlite3.connect(db)
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        rows = con.execute("SELECT class, place, outcome, phases_ms, attempt, scan FROM picks").fetchall()
        con.close()
        assert len(rows) >= len(verified) >= 1, rows
        assert all(r[0] and r[2] and json.loads(r[3]) is not None and r[4] >= 1 for r in rows), rows

        # The restart: nothing resumes, the job is interrupted, the rows are all there. (The killed daemon's socket
        # is left behind: gone before the restart, so that the test waits for the new one.)
        os.unlink(cell.daemon.socket)
        cell.daemon = e2e.Daemon(tmp_path, worldkit.daemon_config(tmp_path, tmp_path / "world.json", cell.scene,
                                                                    cell.world.camera), cell.world.port)
        _, final = cell.daemon.request({"cmd": "history"})
        hist = final["result"]
        assert [j["outcome"] for j in hist["jobs"]] == ["interrupted"], hist["jobs"]
        assert len(hist["picks"]) == len(rows)
        assert sum(p["outcome"] == "picked" for p in hist["picks"]) >= len(verified)
        assert cell.daemon.request({"cmd": "status"})[1]["result"]["job"] is None
        assert cell.daemon.request({"cmd": "pause"})[1]["error"]["code"] == "no_job"
        assert "marked interrupted" in cell.daemon.log_path.read_text()

        # A corrupt database stops the daemon with one line naming it; the file is left as it was.
        cell.daemon.stop()
        junk = bytes(range(256)) * 20
        db.write_bytes(junk)
        for f in (tmp_path / "state").glob("history.sqlite-*"):
            f.unlink()
        r = subprocess.run([str(e2e.BIN / "rbx1d"), "--config", str(cell.daemon.config), "--port", cell.world.port],
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 1, r
        assert f"{db}: the history database is unreadable" in r.stderr and "move the file aside" in r.stderr, r.stderr
        assert db.read_bytes() == junk
    finally:
        cell.stop()
