"""narrow.py - scenes of the narrow-part classes (alone, or touching each other and convex classes) at random
scales and rotations, and their figures against the truth: per class found, single objects split, extra
detections, touching groups split into their members."""
import os

import cv2
import numpy as np

from . import scene, shapes

CONVEX = ["ellipse", "rectangle", "hexagon", "near_circle"]


def generate(out_dir, count, seed, touching):
    """`count` scenes into out_dir (deterministic per seed): 3-5 objects at 30-48 px/cm; `touching`: about half of
    them in touching pairs (narrow classes with each other and with convex ones). Returns the truth documents."""
    os.makedirs(out_dir, exist_ok=True)
    docs = []
    for i in range(count):
        rng = np.random.default_rng([seed, int(touching), i])
        classes = shapes.narrow_class_names() + (CONVEX if touching else [])
        spec = scene.SceneSpec(px_per_cm=float(rng.uniform(30, 48)), classes=classes, min_objects=3,
                               max_objects=5, p_touching=1.0 if touching else 0.0, p_near=0.3)
        names = [str(n) for n in rng.choice(shapes.narrow_class_names(), size=int(rng.integers(3, 6)))]
        if touching:  # every other object convex, so narrow ones meet convex ones as well as each other
            names = [n if k % 2 == 0 else str(rng.choice(CONVEX)) for k, n in enumerate(names)]
        image, background, doc = scene.render_scene(rng, spec, names)
        docs.append(scene.write(os.path.join(out_dir, f"scene_{i:04d}"), image, background,
                                dict(doc, seed=seed, index=i)))
    return docs


def inside_object(obj, point, tol=2.0):
    """The point lies in the object (2 px slack) or near its centroid (an open ring's lies in its hole)."""
    if np.hypot(point[0] - obj["centroid_px"][0], point[1] - obj["centroid_px"][1]) <= 10:
        return True
    poly = np.asarray(obj["polygon_px"], np.float32)
    return cv2.pointPolygonTest(poly, (float(point[0]), float(point[1])), True) >= -tol


def score(truth, detections):
    """Per scene: each truth object's detections (centroid inside its polygon, 2 px slack). Returns
    dict(per_class={class: [objects, found, split]}, extra=n, groups=n, groups_split=n, groups_cut=n):
    a single object is found with one detection inside it and split with two or more; a touching group is split
    (as wanted) when each member holds exactly one, and cut when a member holds two or more."""
    objs = truth["objects"]
    inside = {o["id"]: [k for k, d in enumerate(detections) if inside_object(o, d["centroid_px"])] for o in objs}
    used = set(k for v in inside.values() for k in v)
    out = {"per_class": {}, "extra": len(detections) - len(used), "groups": 0, "groups_split": 0, "groups_cut": 0}
    for o in objs:
        if o["touching"]:
            continue
        c = out["per_class"].setdefault(o["class"], [0, 0, 0])
        n = len(inside[o["id"]])
        c[0] += 1
        c[1] += n >= 1
        c[2] += n >= 2
    for a, b in truth["touching_pairs"]:
        out["groups"] += 1
        out["groups_split"] += len(inside[a]) == 1 and len(inside[b]) == 1
        out["groups_cut"] += len(inside[a]) >= 2 or len(inside[b]) >= 2
    return out


def total(scores):
    """Sum of score() over scenes."""
    out = {"per_class": {}, "extra": 0, "groups": 0, "groups_split": 0, "groups_cut": 0, "scenes": len(scores)}
    for s in scores:
        for k in ("extra", "groups", "groups_split", "groups_cut"):
            out[k] += s[k]
        for name, v in s["per_class"].items():
            acc = out["per_class"].setdefault(name, [0, 0, 0])
            for i in range(3):
                acc[i] += v[i]
    out["singles"] = sum(v[0] for v in out["per_class"].values())
    out["singles_found"] = sum(v[1] for v in out["per_class"].values())
    out["singles_split"] = sum(v[2] for v in out["per_class"].values())
    return out
