"""hard.py - scenes of issue 27's other hard cases, outside the default mix, and their figures:
- "shaded": light objects on a dark table, each lit from one side: its contrast falls linearly across it, in a
  random direction, to 15-35 % of itself on the far side (the darker side must stay part of the object, and the
  grip's contacts on its outline, not inside it);
- "border": every object laid against an edge of the frame, its outline 1.0-1.8 px from it (nearer, the blur
  puts half the edge pixel over the object): the blurred, anti-aliased rim reaches the edge, the body does not
  (such an object is whole and must be found).
Both at 30-48 px/cm, 2-4 objects of the ten rigid classes, apart (no touching or near pairs)."""
import math
import os

import cv2
import numpy as np

from . import layout, narrow, scene, shapes

KINDS = ("shaded", "border")
BORDER_GAP_PX = (1.0, 1.8)


def _border_layout(rng, spec, names):
    """Each object against a frame edge (sides in turn from a random one), BORDER_GAP_PX from it, at least
    min_gap_px from the others; an object with no room after 200 tries is left out."""
    W, H = spec.width, spec.height
    objs = []
    side0 = int(rng.integers(4))
    for i, name in enumerate(names):
        side = (side0 + i) % 4
        for _ in range(200):
            angle = float(rng.uniform(-180, 180))
            poly = shapes.place(shapes.polygon_cm(name), spec.px_per_cm, angle, (0.0, 0.0))
            g = float(rng.uniform(*BORDER_GAP_PX))
            # The outline's extreme towards that side, g px inside the frame's edge (pixel centres at integers,
            # the edge at -0.5 and W - 0.5); a random place along the side.
            lo, hi = poly.min(axis=0), poly.max(axis=0)
            if side in (0, 2):  # left, right
                x = (-0.5 + g - lo[0]) if side == 0 else (W - 0.5 - g - hi[0])
                y = float(rng.uniform(-lo[1] + 12, H - hi[1] - 12))
            else:  # top, bottom
                y = (-0.5 + g - lo[1]) if side == 1 else (H - 0.5 - g - hi[1])
                x = float(rng.uniform(-lo[0] + 12, W - hi[0] - 12))
            placed = poly + np.array([x, y])
            if not layout.inside_image(placed, W, H, 0.0):
                continue
            if all(layout.boxes_apart(placed, o[3], spec.min_gap_px) or
                   layout.gap(placed, o[3]) >= spec.min_gap_px for o in objs):
                centre = np.array([x, y])
                objs.append((name, angle, centre, placed))
                break
    return objs, [], []


def generate(out_dir, count, seed, kind):
    """`count` scenes of `kind` into out_dir (deterministic per seed and kind). Returns the truth documents."""
    if kind not in KINDS:
        raise ValueError(f"unknown kind {kind!r} (known: {', '.join(KINDS)})")
    os.makedirs(out_dir, exist_ok=True)
    docs = []
    for i in range(count):
        rng = np.random.default_rng([seed, KINDS.index(kind) + 2, i])
        spec = scene.SceneSpec(px_per_cm=float(rng.uniform(30, 48)), min_objects=2, max_objects=4, p_touching=0.0,
                               p_near=0.0, p_shadow=0.0, shaded=(0.15, 0.35) if kind == "shaded" else None)
        names = [str(n) for n in rng.choice(shapes.class_names(), size=int(rng.integers(2, 5)))]
        placed = _border_layout(rng, spec, names) if kind == "border" else None
        image, background, doc = scene.render_scene(rng, spec, names, polarity="light" if kind == "shaded" else None,
                                                    placed=placed)
        docs.append(scene.write(os.path.join(out_dir, f"scene_{i:04d}"), image, background,
                                dict(doc, seed=seed, index=i, kind=kind)))
    return docs


def contact_depth(obj, grip):
    """How far the deeper of a grip's two contacts lies inside the object's true outline (px; negative: both
    outside it). A finger closing from outside touches the outline: a contact inside is a finger in the material."""
    poly = np.asarray(obj["polygon_px"], np.float32)
    return max(cv2.pointPolygonTest(poly, (float(p[0]), float(p[1])), True) for p in (grip["p1_px"], grip["p2_px"]))


def score(truth, detections):
    """narrow.score's counts, plus per single object found once: centroid error (px) and contact depth (px)."""
    s = narrow.score(truth, detections)
    s["centroid_err"], s["contact_depth"] = [], []
    for o in truth["objects"]:
        inside = [d for d in detections if narrow.inside_object(o, d["centroid_px"])]
        if len(inside) != 1:
            continue
        d = inside[0]
        s["centroid_err"].append(math.hypot(d["centroid_px"][0] - o["centroid_px"][0],
                                            d["centroid_px"][1] - o["centroid_px"][1]))
        s["contact_depth"].append(contact_depth(o, d["grip"]))
    return s


def total(scores):
    """narrow.total, plus the centroid errors and contact depths of every scene."""
    t = narrow.total(scores)
    t["centroid_err"] = [e for s in scores for e in s["centroid_err"]]
    t["contact_depth"] = [e for s in scores for e in s["contact_depth"]]
    return t
