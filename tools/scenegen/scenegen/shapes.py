"""shapes.py - the object catalogue: each class is one rigid object with fixed dimensions (cm), as a polygon."""
import math

import numpy as np


def _rect(w, h):
    return np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]], float)


def _ellipse(a, b, n=256):
    t = np.arange(n) * 2 * math.pi / n
    return np.column_stack([a * np.cos(t), b * np.sin(t)])


def _rounded_rect(w, h, r, n_arc=32):
    pts = []
    for cx, cy, start in ((w / 2 - r, h / 2 - r, 0.0), (-w / 2 + r, h / 2 - r, 90.0),
                          (-w / 2 + r, -h / 2 + r, 180.0), (w / 2 - r, -h / 2 + r, 270.0)):
        for k in range(n_arc + 1):
            t = math.radians(start + 90.0 * k / n_arc)
            pts.append([cx + r * math.cos(t), cy + r * math.sin(t)])
    return np.array(pts, float)


def _l_shape(length, height, thickness):
    # Long arm along +x at the bottom (y down is "bottom" in the image), short arm up at the left end.
    return np.array([[0, 0], [thickness, 0], [thickness, height - thickness], [length, height - thickness],
                     [length, height], [0, height]], float)


def _t_shape(bar_w, bar_h, stem_w, stem_h):
    return np.array([[-bar_w / 2, 0], [bar_w / 2, 0], [bar_w / 2, bar_h], [stem_w / 2, bar_h],
                     [stem_w / 2, bar_h + stem_h], [-stem_w / 2, bar_h + stem_h], [-stem_w / 2, bar_h],
                     [-bar_w / 2, bar_h]], float)


def _star(points, r_out, r_in):
    pts = []
    for k in range(2 * points):
        r = r_out if k % 2 == 0 else r_in
        t = -math.pi / 2 + k * math.pi / points
        pts.append([r * math.cos(t), r * math.sin(t)])
    return np.array(pts, float)


def _regular(n, r):
    t = np.arange(n) * 2 * math.pi / n
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


def _mirror(poly):
    # Mirror about the y axis; reverse the order to keep the winding.
    m = poly.copy()
    m[:, 0] = -m[:, 0]
    return m[::-1].copy()


# name -> (polygon in cm, description). Sizes are 1-4 cm like the paper's objects on its 12 cm x 12 cm scene.
CLASSES = {
    "rectangle": (_rect(3.0, 1.5), "3.0 x 1.5 cm rectangle"),
    "ellipse": (_ellipse(1.45, 0.8), "2.9 x 1.6 cm ellipse"),
    "rounded_rect": (_rounded_rect(3.4, 1.9, 0.55), "3.4 x 1.9 cm rectangle, 0.55 cm corner radius"),
    "l_shape": (_l_shape(3.2, 1.9, 0.75), "L: 3.2 cm long arm, 1.9 cm short arm, 0.75 cm thick"),
    "l_mirror": (_mirror(_l_shape(3.2, 1.9, 0.75)), "the mirror image of l_shape"),
    "t_shape": (_t_shape(3.0, 0.75, 0.8, 1.9), "T: 3.0 x 0.75 cm bar, 0.8 x 1.9 cm stem"),
    "triangle": (np.array([[0, 0], [3.3, 0], [0.9, 1.7]], float), "scalene triangle 3.3 cm base, 1.7 cm high"),
    "star": (_star(5, 1.45, 0.62), "five-pointed star, 1.45 / 0.62 cm radii"),
    "near_circle": (_ellipse(1.1, 1.03), "almost round disc, 2.2 x 2.06 cm"),
    "hexagon": (_regular(6, 1.25), "regular hexagon, 1.25 cm corner radius"),
}

MIRROR_PAIRS = [("l_shape", "l_mirror")]


# Classes with narrow parts (issue 27): one object each, whose stem, prongs, teeth, handle or tentacles are
# narrower than its body; the touching-object split must not cut them off. Outside the default class mix (the
# default scenes stay as they were); built as unions of simple parts (shapes_union.py), traced to one polygon.
def _narrow_classes():
    from . import shapes_union as u
    return {
        "fruit_leaf": (u.fruit_leaf(), "2.2 cm disc, 0.12 cm stem 0.5 cm long, 1.1 x 0.44 cm leaf at its end"),
        "crown": (u.crown(), "3.0 x 0.9 cm band, five 0.16 cm prongs 0.6-0.9 cm long, each with a 0.2 cm ball"),
        "gear": (u.gear(), "gear: 12 teeth, 1.1 / 1.45 cm root / tip radii"),
        "pan": (u.pan(), "2.0 cm disc, 0.22 cm neck about 1 cm long, 1.2 x 0.5 cm grip"),
        "jellyfish": (u.jellyfish(), "2.6 x 0.9 cm dome, five wavy 0.14 cm tentacles ending in 0.17 cm bulbs"),
        "c_ring": (u.c_ring(), "open ring: 1.3 / 0.85 cm radii, 50 degree gap"),
        "key": (u.key(), "1.4 cm head, 0.3 x 2.2 cm shaft, two bits"),
    }


NARROW_CLASSES = _narrow_classes()


def _notched_rect(w, h, notch_w, notch_d, notch_x):
    # A notch notch_w wide and notch_d deep in the side at +h/2, centred at x = notch_x.
    a, b = notch_x - notch_w / 2, notch_x + notch_w / 2
    return np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [b, h / 2], [b, h / 2 - notch_d],
                     [a, h / 2 - notch_d], [a, h / 2], [-w / 2, h / 2]], float)


def _flat_disc(r, cut, n=256):
    # A disc with the part beyond x = cut (0 < cut < r) sliced off: a straight flat.
    t0 = math.acos(cut / r)
    t = t0 + np.arange(n + 1) * (2 * math.pi - 2 * t0) / n
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


# Near-twin pairs (issue 27): two classes that differ slightly (10 % longer, a small notch, a flat, a longer
# arm), so that a taught one and its untaught twin score alike. Outside the default mix (twins.py, the bench
# tools/bench/perception-twins).
TWIN_CLASSES = {
    "plate": (_rect(2.4, 1.0), "2.4 x 1.0 cm rectangle"),
    "plate_long": (_rect(2.64, 1.0), "the plate 10 % longer: 2.64 x 1.0 cm"),
    "tab": (_rect(2.4, 1.6), "2.4 x 1.6 cm rectangle"),
    "tab_notch": (_notched_rect(2.4, 1.6, 0.4, 0.3, 0.5), "the tab with a 0.4 x 0.3 cm notch in a long side"),
    "disc": (_ellipse(1.5, 1.5), "3.0 cm disc"),
    "disc_flat": (_flat_disc(1.5, 1.2), "the disc with a flat 0.3 cm deep"),
    "bracket": (_l_shape(2.6, 2.0, 0.9), "L: 2.6 cm long arm, 2.0 cm short arm, 0.9 cm thick"),
    "bracket_long": (_l_shape(2.6, 2.2, 0.9), "the bracket with its short arm 10 % longer (2.2 cm)"),
}
TWIN_PAIRS = [("plate", "plate_long"), ("tab", "tab_notch"), ("disc", "disc_flat"), ("bracket", "bracket_long")]
ALL_CLASSES = {**CLASSES, **NARROW_CLASSES, **TWIN_CLASSES}


def class_names():
    return list(CLASSES)


def narrow_class_names():
    return list(NARROW_CLASSES)


def polygon_cm(name):
    """The class's polygon in its own frame (cm), centred on its area centroid."""
    from .truth import area_centroid
    poly = ALL_CLASSES[name][0]
    return poly - area_centroid(poly)


def place(poly_cm, px_per_cm, angle_deg, centre_px):
    """Rotate (from +x towards +y, degrees), scale to pixels and move the area centroid to centre_px."""
    t = math.radians(angle_deg)
    rot = np.array([[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]])
    return (poly_cm * px_per_cm) @ rot.T + np.asarray(centre_px, float)
