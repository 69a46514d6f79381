"""silhouettes.py - the real silhouettes of data/corpus/silhouettes (drawn outlines of real things with narrow
parts: an apple's stem and leaf, a crown's prongs, a jellyfish's tentacles, a horse's legs...), their reference
made from each file's own mask, independently of rbx1 detect, and the frames shown to it.

Reference (`reference`): the file's object fraction per pixel f (its grey scaled to 0..1, inverted for a dark
object on white); the object's pixels are f >= 0.5; their 8-connected components are counted (`components`,
areas), the largest is the object; its area is the sum of f over it and a 1 px ring (the anti-aliased rim), its
centroid the f-weighted mean pixel position over the same pixels (pixel centres at integers, as rbx1 reports).
Frame (`frame`): the file laid on a plain table MARGIN_PX from every side, each pixel table + (object - table) x f:
a dark object (70) on a light table (185), or a light one (200) on a dark table (60); the table alone is the
captured background. Nothing else is done to it (no blur, no noise): what rbx1 sees is the file's own outline."""
import glob
import os

import cv2
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
DIR = os.path.join(ROOT, "data", "corpus", "silhouettes")
MARGIN_PX = 40
LEVELS = {"dark": (185, 70), "light": (60, 200)}  # polarity -> (table, object)
DARK_ON_WHITE = {"horse.png"}  # the others are white objects on black


def files():
    return sorted(glob.glob(os.path.join(DIR, "*.png")))


def fraction(path):
    """The object fraction of each pixel (0..1, float64)."""
    g = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if g is None:
        raise ValueError(f"{path}: not a readable image")
    f = g.astype(np.float64) / 255.0
    return 1.0 - f if os.path.basename(path) in DARK_ON_WHITE else f


def reference(path):
    """dict(components=[areas, largest first], area_px, centroid_px) in the file's own pixel coordinates."""
    f = fraction(path)
    mask = (f >= 0.5).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    areas = sorted((int(a) for a in stats[1:, cv2.CC_STAT_AREA]), reverse=True)
    biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    near = cv2.dilate((labels == biggest).astype(np.uint8), np.ones((3, 3), np.uint8))
    w = f * near
    ys, xs = np.mgrid[0:f.shape[0], 0:f.shape[1]]
    a = float(w.sum())
    return {"components": areas, "area_px": a,
            "centroid_px": [float((w * xs).sum() / a), float((w * ys).sum() / a)]}


def outline_cm(path, size_cm):
    """The file's object as one polygon in cm (image axes, about its area centroid), its longer side size_cm:
    the outer contour of the largest component of f >= 0.5 (holes are not kept: a part's outline), simplified to
    0.5 px. For a world that lays the silhouette out as a part (tools/world/make-world)."""
    from .truth import area_centroid
    mask = (fraction(path) >= 0.5).astype(np.uint8)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(contours, key=cv2.contourArea)
    poly = cv2.approxPolyDP(c, 0.5, True).reshape(-1, 2).astype(np.float64)
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    poly *= size_cm / float(max(hi - lo))
    return poly - area_centroid(poly)


def frame(path, polarity):
    """(frame BGR uint8, captured background BGR uint8, offset (x, y) of the file's pixels in the frame)."""
    f = fraction(path)
    table, obj = LEVELS[polarity]
    f = cv2.copyMakeBorder(f, MARGIN_PX, MARGIN_PX, MARGIN_PX, MARGIN_PX, cv2.BORDER_CONSTANT, value=0.0)
    img = np.clip(np.rint(table + (obj - table) * f), 0, 255).astype(np.uint8)
    bg = np.full_like(img, table)
    return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR), cv2.cvtColor(bg, cv2.COLOR_GRAY2BGR), (MARGIN_PX, MARGIN_PX)
