"""twins.py - scenes of the near-twin pairs (shapes.TWIN_PAIRS: a class and its slightly different twin), and
their identification figures: right / unknown / wrong per object, with one twin of each pair taught, both, or
neither (issue 27: an untaught look-alike stays unknown)."""
import os

import numpy as np

from . import scene, shapes

PX_PER_CM = 40.0


def twin_names():
    return [n for pair in shapes.TWIN_PAIRS for n in pair]


def generate(out_dir, count, seed):
    """`count` scenes into out_dir (deterministic per seed): 3-5 twin-pair objects, apart or near (not touching:
    the figures are about identification, not the split), the default tables, light, shadows and noise.
    Returns the truth documents."""
    os.makedirs(out_dir, exist_ok=True)
    docs = []
    for i in range(count):
        rng = np.random.default_rng([seed, 27, i])
        spec = scene.SceneSpec(px_per_cm=PX_PER_CM, classes=twin_names(), min_objects=3, max_objects=5,
                               p_touching=0.0, p_near=0.3)
        names = [str(n) for n in rng.choice(twin_names(), size=int(rng.integers(3, 6)))]
        image, background, doc = scene.render_scene(rng, spec, names)
        docs.append(scene.write(os.path.join(out_dir, f"scene_{i:04d}"), image, background,
                                dict(doc, seed=seed, index=i)))
    return docs


def teach_images(out_dir, names, seed=1):
    """One teach image per class (scene.teach_image: one dark object on a plain light table) into out_dir."""
    os.makedirs(out_dir, exist_ok=True)
    for name in names:
        image, background, doc = scene.teach_image(name, px_per_cm=PX_PER_CM, seed=seed)
        scene.write(os.path.join(out_dir, name), image, background, dict(doc, seed=seed))


def _nearest(obj, detections, used, tol=10.0):
    best, dist = None, tol
    for k, d in enumerate(detections):
        e = float(np.hypot(d["centroid_px"][0] - obj["centroid_px"][0], d["centroid_px"][1] - obj["centroid_px"][1]))
        if k not in used and e <= dist:
            best, dist = k, e
    return best


def score(truth, detections, taught):
    """Per object of the scene: its outcome against the library's taught names. A taught class is right when
    labelled as itself, unknown when not labelled, wrong when labelled as another; an untaught class is right when
    unknown and wrong when labelled. A missed object is counted as missed. Returns a list of
    dict(cls, taught, outcome, label, best, best_score, threshold, runner_up, margin)."""
    out, used = [], set()
    for o in truth["objects"]:
        k = _nearest(o, detections, used)
        row = {"cls": o["class"], "taught": o["class"] in taught}
        if k is None:
            out.append(dict(row, outcome="missed"))
            continue
        used.add(k)
        d = detections[k]
        label, ident = d.get("label"), d.get("identification") or {}
        if row["taught"]:
            outcome = "right" if label == o["class"] else ("unknown" if label is None else "wrong")
        else:
            outcome = "right" if label is None else "wrong"
        out.append(dict(row, outcome=outcome, label=label, best=ident.get("best"),
                        best_score=ident.get("best_score", d.get("match_score")),
                        threshold=ident.get("threshold"), runner_up=ident.get("runner_up"),
                        margin=ident.get("margin")))
    return out


def tally(rows):
    """Counts of outcomes for taught and untaught objects: {"taught": {right, unknown, wrong, missed, objects},
    "untaught": {right (= unknown), wrong, missed, objects}}."""
    out = {}
    for key, flag in (("taught", True), ("untaught", False)):
        sel = [r for r in rows if r["taught"] == flag]
        c = {"objects": len(sel)}
        for outcome in ("right", "unknown", "wrong", "missed"):
            c[outcome] = sum(r["outcome"] == outcome for r in sel)
        out[key] = c
    return out
