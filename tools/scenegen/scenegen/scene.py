"""scene.py - one scene: objects laid out, rendered over a table with light, shadows, blur and noise, and its
exact ground truth; also the empty-scene image of the same table (for --background) and single-object teach images."""
import json
import math
import os

import cv2
import numpy as np

from . import layout, render, shapes, truth

GENERATOR_VERSION = 1
ELONGATED_ASPECT = 1.5
TABLE_KINDS = ["uniform", "wood", "cloth", "blotches", "tiles"]


class SceneSpec:
    """Knobs of the random scene distribution (defaults: the accuracy benchmark's)."""

    def __init__(self, width=640, height=480, px_per_cm=40.0, min_objects=3, max_objects=6,
                 classes=None, p_touching=0.25, p_near=0.4, p_light=0.5, p_pattern=0.5, p_shadow=0.35,
                 blur=(0.5, 1.1), noise=(1.0, 3.5), light_strength=(0.05, 0.2), min_gap_px=14.0,
                 border_px=10.0, p_mixed=0.0, light_drift=0.0, shadow_offset=(2.0, 5.0),
                 shadow_sigma=(2.5, 4.5), shadow_strength=(0.08, 0.18), p_colour=0.0, shaded=None):
        self.width, self.height, self.px_per_cm = width, height, px_per_cm
        self.min_objects, self.max_objects = min_objects, max_objects
        self.classes = list(classes or shapes.class_names())
        self.p_touching, self.p_near, self.p_light = p_touching, p_near, p_light
        self.p_pattern, self.p_shadow = p_pattern, p_shadow
        self.blur, self.noise, self.light_strength = blur, noise, light_strength
        self.min_gap_px, self.border_px = min_gap_px, border_px
        # Variants (off by default, so the default scenes stay as they were): mixed polarity, dark and light
        # objects on a mid-grey table, in p_mixed of the scenes; light drift, the scene lit with a gain in
        # 1 +- light_drift and a black-level offset of up to +-10 levels against its empty-table image.
        self.p_mixed, self.light_drift = p_mixed, light_drift
        # Cast shadows: offset from the objects (px), blur (px), darkening ratio (every channel alike).
        self.shadow_offset, self.shadow_sigma = shadow_offset, shadow_sigma
        self.shadow_strength = shadow_strength
        # Colour tables (p_colour of the scenes): a saturated, textured table and saturated objects of other
        # hues, each object's grey level at least 40 from the table's (the detector thresholds grey).
        self.p_colour = p_colour
        # Shaded objects (issue 27; None = off): each object lit from one side, its contrast against the table
        # falling linearly across it, in a random direction, to a fraction drawn from this range on the far side.
        self.shaded = shaded


def _placed(name, px_per_cm, angle, centre):
    return shapes.place(shapes.polygon_cm(name), px_per_cm, angle, centre)


def _layout(rng, spec, names):
    """Poses for the named objects; returns (list of (name, angle, centre, poly)), near pairs, touching pairs."""
    objs, near, touching = [], [], []
    W, H, s = spec.width, spec.height, spec.px_per_cm

    def clear_of_others(poly, skip=()):
        return all(k in skip or layout.boxes_apart(poly, o[3], spec.min_gap_px) or
                   layout.gap(poly, o[3]) >= spec.min_gap_px for k, o in enumerate(objs))

    i = 0
    while i < len(names):
        name = names[i]
        pair_kind = None
        if objs:
            # About p_touching (p_near) pairs per scene of this size: each later object may join an earlier one.
            r = rng.random()
            if r < spec.p_touching / len(names) * 2:
                pair_kind = "touching"
            elif r < (spec.p_touching + spec.p_near) / len(names) * 2:
                pair_kind = "near"
        placed = False
        for _ in range(200):
            angle = float(rng.uniform(-180, 180))
            if pair_kind and objs:
                k = int(rng.integers(len(objs)))
                if any(k in p[:2] for p in touching):  # keep merged blobs to two objects
                    continue
                base = objs[k][3]
                c0 = truth.area_centroid(base)
                th = rng.uniform(0, 2 * math.pi)
                u = np.array([math.cos(th), math.sin(th)])
                target = 0.0 if pair_kind == "touching" else float(rng.uniform(3.0, 8.0))
                off = layout.at_gap(base, lambda d: _placed(name, s, angle, c0 + d * u), u, target,
                                    far=6 * s)
                if off is None:
                    continue
                centre = c0 + off * u
                poly = _placed(name, s, angle, centre)
                if not layout.inside_image(poly, W, H, spec.border_px) or not clear_of_others(poly, skip=(k,)):
                    continue
                g = layout.gap(base, poly)
                objs.append((name, angle, centre, poly))
                (touching if pair_kind == "touching" else near).append((k, len(objs) - 1, max(g, 0.0)))
            else:
                centre = rng.uniform([0, 0], [W, H])
                poly = _placed(name, s, angle, centre)
                if not layout.inside_image(poly, W, H, spec.border_px) or not clear_of_others(poly):
                    continue
                objs.append((name, angle, centre, poly))
            placed = True
            break
        if not placed and pair_kind:
            continue  # no room for that pair: draw this object's pairing again
        i += 1
    return objs, near, touching


def _colour(rng, level):
    return np.clip(level + rng.normal(0, 6, 3), 0, 255)


GREY_WEIGHTS = np.array([0.114, 0.587, 0.299])  # B, G, R as in cv2.cvtColor(BGR2GRAY)


def _hue_bgr(hue_deg, saturation, grey):
    """A BGR colour of the given hue (0-360) and saturation (0-1) whose grey level is `grey`."""
    h = math.radians(hue_deg)
    # Chroma direction in RGB around grey, then scaled so the grey level comes out exactly.
    rgb = np.array([math.cos(h), math.cos(h - 2 * math.pi / 3), math.cos(h + 2 * math.pi / 3)])
    bgr = 1.0 + saturation * rgb[::-1]
    bgr = bgr * grey / float(GREY_WEIGHTS @ bgr)
    return np.clip(bgr, 0, 255)


def _colour_table(rng):
    """(hue, saturation, grey level) of a coloured table: a green cutting mat, a brown wood, a blue cloth..."""
    return float(rng.uniform(0, 360)), float(rng.uniform(0.35, 0.6)), float(rng.uniform(90, 170))


def _colour_object(rng, table_hue, table_grey):
    """A saturated object colour: a hue at least 90 degrees from the table's, grey level 40-90 from it."""
    hue = (table_hue + rng.uniform(90, 270)) % 360
    grey = table_grey + rng.choice([-1, 1]) * rng.uniform(40, 90)
    if grey < 25 or grey > 235:
        grey = table_grey - np.sign(grey - table_grey) * rng.uniform(40, 90)
    return _hue_bgr(hue, float(rng.uniform(0.4, 0.8)), float(np.clip(grey, 15, 245)))


def _shaded(rng, fractions, obj, xx, yy, xs, ys, table_level):
    """The object lit from one side: its contrast against the table falls linearly along a random direction,
    from whole on its lit side to a fraction (drawn from `fractions`) on the far side."""
    th = rng.uniform(0, 2 * math.pi)
    f = rng.uniform(*fractions)
    along = math.cos(th) * xx + math.sin(th) * yy
    span = math.cos(th) * xs + math.sin(th) * ys
    t = np.clip((along - span.min()) / max(span.max() - span.min(), 1e-9), 0, 1)
    return table_level + (obj - table_level) * (1 - (1 - f) * t)[..., None], {"towards_deg": math.degrees(th),
                                                                             "far_fraction": f}


def render_scene(rng, spec, names, polarity=None, table_kind=None, shadow=None, empty=False, placed=None):
    """Returns (scene BGR uint8, background BGR uint8, truth dict). `placed`: a fixed layout (objs, near,
    touching) instead of a random one."""
    W, H = spec.width, spec.height
    colour = None
    if polarity is None and spec.p_colour > 0 and rng.random() < spec.p_colour:
        polarity, colour = "colour", _colour_table(rng)
    if polarity is None and spec.p_mixed > 0 and rng.random() < spec.p_mixed:
        polarity = "mixed"
    polarity = polarity or ("light" if rng.random() < spec.p_light else "dark")
    if table_kind is None:
        table_kind = "uniform" if rng.random() >= spec.p_pattern else str(rng.choice(TABLE_KINDS[1:]))
    if polarity == "dark":
        table_level, obj_range, amp = rng.uniform(165, 215), (30, 90), rng.uniform(6, 14)
    elif polarity == "mixed":
        table_level, obj_range, amp = rng.uniform(110, 140), None, rng.uniform(5, 10)
    elif polarity == "colour":
        table_level, obj_range, amp = colour[2], None, rng.uniform(6, 14)
    else:
        table_level, obj_range, amp = rng.uniform(35, 80), (165, 225), rng.uniform(5, 10)
    amp = 0.0 if table_kind == "uniform" else amp
    if placed is not None:
        objs, near, touching = placed
    else:
        objs, near, touching = ([], [], []) if empty else _layout(rng, spec, names)

    surface = render.table(rng, (H, W), table_kind, table_level, amp)
    if colour is None:
        tint = rng.normal(0, 5, 3)
        table_bgr = np.stack([surface + t for t in tint], axis=2)
    else:  # the pattern modulates a saturated colour (texture in every channel, in proportion)
        base = _hue_bgr(colour[0], colour[1], table_level)
        table_bgr = (surface / table_level)[..., None] * base[None, None, :]
    light = render.illumination(rng, (H, W), rng.uniform(*spec.light_strength))

    alphas = [render.coverage(o[3], (H, W)) for o in objs]
    scene = table_bgr.copy()
    if shadow is None:
        shadow = bool(objs) and rng.random() < spec.p_shadow
    shadow_info = None
    if shadow and objs:
        total = np.clip(sum(alphas), 0, 1)
        th = rng.uniform(0, 2 * math.pi)
        dist = rng.uniform(*spec.shadow_offset)
        sigma, strength = rng.uniform(*spec.shadow_sigma), rng.uniform(*spec.shadow_strength)
        m = render.shadow_mask(total, dist * math.cos(th), dist * math.sin(th), sigma)
        scene *= (1.0 - strength * m)[..., None]
        shadow_info = {"offset_px": [dist * math.cos(th), dist * math.sin(th)], "sigma_px": sigma,
                       "strength": strength}
    levels, shading = [], {}
    for a in alphas:
        if colour is not None:
            col = _colour_object(rng, colour[0], table_level)
            level = float(GREY_WEIGHTS @ col)
        elif obj_range is None:  # mixed: each object dark or light at random
            level = rng.uniform(20, 60) if rng.random() < 0.5 else rng.uniform(190, 235)
        else:
            level = rng.uniform(*obj_range)
        levels.append(level)
        if colour is None:
            col = _colour(rng, level)
        gx, gy = rng.normal(0, 0.02, 2)
        ys, xs = np.nonzero(a > 0)
        if not len(xs):
            continue
        # Within the object's box: a faint shading across it (real objects are not perfectly flat in colour).
        y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
        yy, xx = np.mgrid[y0:y1, x0:x1]
        shade = gx * (xx - xs.mean()) + gy * (yy - ys.mean())
        ab = a[y0:y1, x0:x1, None]
        obj = col[None, None, :] + shade[..., None]
        if spec.shaded:
            obj, shading[len(levels) - 1] = _shaded(rng, spec.shaded, obj, xx, yy, xs, ys, table_level)
        scene[y0:y1, x0:x1] = scene[y0:y1, x0:x1] * (1 - ab) + obj * ab
    blur = float(rng.uniform(*spec.blur))
    noise = float(rng.uniform(*spec.noise))
    drift = None
    lit = scene * light[..., None]
    if spec.light_drift > 0:
        drift = {"gain": float(rng.uniform(1 - spec.light_drift, 1 + spec.light_drift)),
                 "offset": float(rng.uniform(-10, 10))}
        lit = lit * drift["gain"] + drift["offset"]
    image = render.finish(lit, rng, blur, noise)
    background = render.finish(table_bgr * light[..., None], rng, blur, noise)

    s = spec.px_per_cm
    touching_ids = {}
    for a, b, _ in touching:
        touching_ids.setdefault(a, []).append(b)
        touching_ids.setdefault(b, []).append(a)
    near_ids = {}
    for a, b, _ in near:
        near_ids.setdefault(a, []).append(b)
        near_ids.setdefault(b, []).append(a)
    objects = []
    for k, (name, angle, centre, poly) in enumerate(objs):
        d = truth.describe(poly)
        g = d["grip"]
        objects.append({
            "id": k, "class": name, "rotation_deg": angle,
            "centroid_px": d["centroid"], "centroid_cm": [d["centroid"][0] / s, d["centroid"][1] / s],
            "area_px": d["area"],
            "orientation_deg": d["orientation_deg"], "orientation_area_deg": d["orientation_area_deg"],
            "aspect": d["aspect"], "boundary_ratio": d["boundary_ratio"],
            "elongated": d["aspect"] >= ELONGATED_ASPECT,
            "grip": {"opening_px": g["opening"], "opening_cm": g["opening"] / s, "angle_deg": g["angle_deg"],
                     "p1_px": g["p1"], "p2_px": g["p2"]},
            "touching": sorted(touching_ids.get(k, [])), "near": sorted(near_ids.get(k, [])),
            "contrast": abs(levels[k] - table_level),
            "polygon_px": [[round(x, 4), round(y, 4)] for x, y in poly],
            **({"shading": shading[k]} if k in shading else {}),
        })
    doc = {
        "generator": "rbx1-scenegen", "version": GENERATOR_VERSION,
        "image": {"width": W, "height": H}, "px_per_cm": s,
        "polarity": polarity, "table": {"kind": table_kind, "level": table_level, "pattern_amplitude": amp,
                                        **({"hue_deg": colour[0], "saturation": colour[1]} if colour else {})},
        "blur_sigma_px": blur, "noise_sigma": noise, "shadow": shadow_info, "light_drift": drift,
        "touching_pairs": [[a, b] for a, b, _ in touching],
        "near_pairs": [{"ids": [a, b], "gap_px": g} for a, b, g in near],
        "objects": objects,
    }
    return image, background, doc


def write(prefix, image, background, doc):
    """prefix.png, prefix.bg.png, prefix.json (PNG is lossless: the truth stays exact)."""
    os.makedirs(os.path.dirname(prefix) or ".", exist_ok=True)
    cv2.imwrite(prefix + ".png", image, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    cv2.imwrite(prefix + ".bg.png", background, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    doc = dict(doc, scene=os.path.basename(prefix) + ".png", background=os.path.basename(prefix) + ".bg.png")
    with open(prefix + ".json", "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    return doc


def class_cycle(rng, classes, count):
    """`count` class names, every class about equally often, in random order."""
    out = []
    while len(out) < count:
        batch = list(classes)
        rng.shuffle(batch)
        out.extend(batch)
    return out[:count]


def _one(job):
    out_dir, seed, spec, kind, i, names = job
    # Each scene has its own generator seeded by (seed, index): the same scene whatever the job split.
    if kind == "scene":
        image, background, doc = render_scene(np.random.default_rng([seed, i]), spec, names)
    else:
        image, background, doc = render_scene(np.random.default_rng([seed, 1_000_000 + i]), spec, [], empty=True)
    return write(os.path.join(out_dir, f"{kind}_{i:04d}"), image, background, dict(doc, seed=seed, index=i))


def generate(out_dir, count, seed, spec=None, empty=0, jobs=1):
    """`count` scenes (scene_NNNN) and `empty` empty scenes (empty_NNNN) into out_dir, deterministic for a
    seed; returns the list of truth documents."""
    spec = spec or SceneSpec()
    rng = np.random.default_rng(seed)
    sizes = rng.integers(spec.min_objects, spec.max_objects + 1, size=count)
    pool = class_cycle(rng, spec.classes, int(sizes.sum()))
    work, used = [], 0
    for i in range(count):
        work.append((out_dir, seed, spec, "scene", i, pool[used:used + sizes[i]]))
        used += sizes[i]
    work += [(out_dir, seed, spec, "empty", i, []) for i in range(empty)]
    os.makedirs(out_dir, exist_ok=True)
    if jobs > 1:
        import multiprocessing
        with multiprocessing.get_context("fork").Pool(jobs) as pool_:
            return pool_.map(_one, work, chunksize=4)
    return [_one(w) for w in work]


def teach_image(name, px_per_cm=40.0, angle=None, seed=0, size=(480, 360), noise=1.5):
    """One object of class `name` on a plain light table, dark, lightly blurred and noisy (a taught object)."""
    rng = np.random.default_rng([seed, list(shapes.ALL_CLASSES).index(name)])
    spec = SceneSpec(width=size[0], height=size[1], px_per_cm=px_per_cm, p_shadow=0, blur=(0.7, 0.7),
                     noise=(noise, noise), light_strength=(0.03, 0.03))
    angle = float(rng.uniform(-180, 180)) if angle is None else angle
    centre = np.array([size[0] / 2 + rng.uniform(-3, 3), size[1] / 2 + rng.uniform(-3, 3)])
    poly = _placed(name, px_per_cm, angle, centre)
    if not layout.inside_image(poly, size[0], size[1], spec.border_px):
        raise ValueError(f"{name} does not fit a {size[0]}x{size[1]} teach image at {px_per_cm} px/cm")
    return render_scene(rng, spec, [name], polarity="dark", table_kind="uniform", shadow=False,
                        placed=([(name, angle, centre, poly)], [], []))
