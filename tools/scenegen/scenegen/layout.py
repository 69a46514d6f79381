"""layout.py - where objects go: random poses inside the image, apart, near (a small gap) or touching (gap 0)."""
import math

import numpy as np


def _point_segment_dist(pts, a, b):
    """Min distance from each point (n x 2) to any segment a[i]->b[i] (m x 2)."""
    d = b - a
    L2 = np.maximum((d * d).sum(axis=1), 1e-300)
    w = pts[:, None, :] - a[None, :, :]
    t = np.clip((w * d[None]).sum(axis=2) / L2[None], 0.0, 1.0)
    proj = a[None] + t[..., None] * d[None]
    return np.sqrt(((pts[:, None, :] - proj) ** 2).sum(axis=2)).min()


def _inside(pts, poly):
    """Even-odd point-in-polygon for each point."""
    p = poly
    q = np.roll(poly, -1, axis=0)
    x, y = pts[:, 0][:, None], pts[:, 1][:, None]
    crosses = ((p[:, 1][None] > y) != (q[:, 1][None] > y))
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = p[:, 0][None] + (y - p[:, 1][None]) * (q[:, 0] - p[:, 0])[None] / (q[:, 1] - p[:, 1])[None]
    return ((crosses & (x < xi)).sum(axis=1) % 2) == 1


def _segments_cross(p1, q1, p2, q2):
    def orient(a, b, c):
        return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])
    A, B = p1[:, None], q1[:, None]
    C, D = p2[None], q2[None]
    o1, o2 = orient(A, B, C), orient(A, B, D)
    o3, o4 = orient(C, D, A), orient(C, D, B)
    return bool(np.any((o1 * o2 < 0) & (o3 * o4 < 0)))


def boxes_apart(pa, pb, distance):
    """True when the bounding boxes alone show the polygons are at least `distance` apart (a cheap pre-check)."""
    dx = max(pb[:, 0].min() - pa[:, 0].max(), pa[:, 0].min() - pb[:, 0].max(), 0.0)
    dy = max(pb[:, 1].min() - pa[:, 1].max(), pa[:, 1].min() - pb[:, 1].max(), 0.0)
    return (dx * dx + dy * dy) ** 0.5 >= distance


def gap(pa, pb):
    """Distance between two polygons' boundaries; negative (-1) when they overlap."""
    qa, qb = np.roll(pa, -1, axis=0), np.roll(pb, -1, axis=0)
    if _inside(pa, pb).any() or _inside(pb, pa).any() or _segments_cross(pa, qa, pb, qb):
        return -1.0
    return min(_point_segment_dist(pa, pb, qb), _point_segment_dist(pb, pa, qa))


def inside_image(poly, width, height, margin):
    return (poly[:, 0].min() >= margin - 0.5 and poly[:, 1].min() >= margin - 0.5 and
            poly[:, 0].max() <= width - 0.5 - margin and poly[:, 1].max() <= height - 0.5 - margin)


def at_gap(fixed, moving_at, direction, target, far):
    """Offset along `direction` from `fixed`'s centroid where the moving polygon (a function of the offset) has
    the target gap to `fixed`, by bisection between overlap (0) and `far`. None if far is not clear of it."""
    lo, hi = 0.0, far
    if gap(fixed, moving_at(hi)) < target:
        return None
    for _ in range(60):
        mid = (lo + hi) / 2
        if gap(fixed, moving_at(mid)) < target:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-4:
            break
    return hi
