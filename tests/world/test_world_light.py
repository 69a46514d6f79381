"""test_world_light.py - the light drifting against a captured background, in the closed loop (issue 27): the
operator captures the empty table with `rbx1 background` at nominal light, then the world's light goes to the
sweep's extremes (every frame * gain + offset: 0.8 and -10, 1.2 and +10); a scan must find every object (named
as it, within 6 mm of where it lies, no phantom) and every pick by name must land in the place asked for (the
world's state), no part of another class. tools/bench/light-sweep (world_picks) runs every level."""
import pytest

import worldkit


@pytest.mark.parametrize("gain,offset", [(0.8, -10), (1.2, 10)])
def test_every_object_found_and_placed_at_the_light_sweeps_extremes(tmp_path, gain, offset):
    scene = tmp_path / "world.json"
    worldkit.make_world(scene, 4000, objects=4, errors=(0.0, 0.0, 0.0), drift=0.0)
    cell = worldkit.Cell(tmp_path, scene)
    try:
        bg = worldkit.capture_background(cell)
        level = worldkit.light_level(cell, gain, offset)
    finally:
        cell.stop()
    print(f"background {bg['frames']} frames; gain {gain} offset {offset}: {level}")
    assert (level["found"], level["phantoms"]) == (level["expected"], 0) == (4, 0), level
    assert level["placed"] == level["picks"] == 4 and level["wrong"] == 0, level
