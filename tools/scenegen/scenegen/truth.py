"""truth.py - exact geometry of a polygon: area centroid, area and boundary second moments, principal axes,
aspect ratio, and the grip chord (minimum over directions of the chord through the centroid between the
outermost boundary crossings). Angles follow shared/DESIGN.md: from +x towards +y (y down), axes in (-90, 90]."""
import math

import numpy as np


def fold_axis_deg(deg):
    """An axis direction folded into (-90, 90] degrees."""
    deg = math.fmod(deg, 180.0)
    if deg <= -90.0:
        deg += 180.0
    if deg > 90.0:
        deg -= 180.0
    return deg


def _edges(poly):
    p = np.asarray(poly, float)
    return p, np.roll(p, -1, axis=0)


def signed_area(poly):
    p, q = _edges(poly)
    return 0.5 * float(np.sum(p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]))


def area(poly):
    return abs(signed_area(poly))


def area_centroid(poly):
    """Centroid of the polygon's area (shoelace), exact."""
    p, q = _edges(poly)
    cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
    a = 0.5 * cross.sum()
    cx = float(np.sum((p[:, 0] + q[:, 0]) * cross) / (6 * a))
    cy = float(np.sum((p[:, 1] + q[:, 1]) * cross) / (6 * a))
    return np.array([cx, cy])


def area_moments(poly):
    """Central second moments (mu20, mu11, mu02) of the polygon's area, exact (Green's theorem)."""
    c = area_centroid(poly)
    p, q = _edges(np.asarray(poly, float) - c)
    x0, y0, x1, y1 = p[:, 0], p[:, 1], q[:, 0], q[:, 1]
    cross = x0 * y1 - x1 * y0
    sign = 1.0 if signed_area(poly) > 0 else -1.0
    mu20 = sign * float(np.sum(cross * (x0 * x0 + x0 * x1 + x1 * x1)) / 12)
    mu02 = sign * float(np.sum(cross * (y0 * y0 + y0 * y1 + y1 * y1)) / 12)
    mu11 = sign * float(np.sum(cross * (x0 * y1 + 2 * x0 * y0 + 2 * x1 * y1 + x1 * y0)) / 24)
    return mu20, mu11, mu02


def boundary_centroid(poly):
    p, q = _edges(poly)
    length = np.hypot(*(q - p).T)
    return ((p + q) / 2 * length[:, None]).sum(axis=0) / length.sum()


def boundary_moments(poly):
    """Scatter matrix (sxx, sxy, syy) of the boundary with uniform density per unit length about its own
    centroid: the continuous form of the paper's Eq. 8 over evenly spaced edge points."""
    c = boundary_centroid(poly)
    p, q = _edges(np.asarray(poly, float) - c)
    length = np.hypot(*(q - p).T)
    # Integral over a segment a->b of v v^T ds = L * ((a a^T + b b^T) / 3 + (a b^T + b a^T) / 6).
    a, b = p, q
    sxx = np.sum(length * ((a[:, 0] ** 2 + b[:, 0] ** 2) / 3 + a[:, 0] * b[:, 0] / 3))
    syy = np.sum(length * ((a[:, 1] ** 2 + b[:, 1] ** 2) / 3 + a[:, 1] * b[:, 1] / 3))
    sxy = np.sum(length * ((a[:, 0] * a[:, 1] + b[:, 0] * b[:, 1]) / 3 + (a[:, 0] * b[:, 1] + b[:, 0] * a[:, 1]) / 6))
    return float(sxx), float(sxy), float(syy)


def principal_axis(sxx, sxy, syy):
    """(axis in degrees folded to (-90, 90], sqrt of the eigenvalue ratio) of a 2x2 scatter matrix."""
    axis = fold_axis_deg(math.degrees(0.5 * math.atan2(2 * sxy, sxx - syy)))
    half = math.hypot((sxx - syy) / 2, sxy)
    mean = (sxx + syy) / 2
    l1, l2 = mean + half, max(mean - half, 1e-300)
    return axis, math.sqrt(l1 / l2)


def chords(poly, centre, phis):
    """For each angle phi, (tmin, tmax) of the line centre + t (cos phi, sin phi) between its outermost boundary
    crossings; NaN where the line misses the polygon."""
    p, q = _edges(poly)
    d = q - p                                    # E x 2
    u = np.column_stack([np.cos(phis), np.sin(phis)])  # M x 2
    w = p - np.asarray(centre, float)            # E x 2
    denom = u[:, None, 0] * d[None, :, 1] - u[:, None, 1] * d[None, :, 0]      # M x E: cross(u, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[None, :, 0] * d[None, :, 1] - w[None, :, 1] * d[None, :, 0]) / denom   # cross(w, d) / cross(u, d)
        s = (w[None, :, 0] * u[:, None, 1] - w[None, :, 1] * u[:, None, 0]) / denom   # cross(w, u) / cross(u, d)
    hit = (np.abs(denom) > 1e-15) & (s >= 0) & (s <= 1)
    tmin = np.where(hit, t, np.inf).min(axis=1)
    tmax = np.where(hit, t, -np.inf).max(axis=1)
    miss = ~hit.any(axis=1)
    tmin[miss] = np.nan
    tmax[miss] = np.nan
    return tmin, tmax


def grip_chord(poly, centre=None):
    """The minimum over directions of the chord through the centre (default: the area centroid) between the
    outermost boundary crossings. Returns dict(opening, angle_deg, p1, p2); p1 -> p2 is the closing direction."""
    c = area_centroid(poly) if centre is None else np.asarray(centre, float)
    coarse = np.arange(1440) * math.pi / 1440           # 0.125 degree steps over [0, pi)
    tmin, tmax = chords(poly, c, coarse)
    length = tmax - tmin
    best = np.nanmin(length)
    # Refine around each coarse local minimum near the best (several local minima can be close), in two
    # stages: +-0.15 deg in 0.0025 deg steps, then +-0.003 deg in 0.0001 deg steps.
    prev, nxt = np.roll(length, 1), np.roll(length, -1)
    local = (length <= prev) & (length <= nxt) & (length <= best * 1.01 + 1e-12)
    candidates = np.flatnonzero(local)
    candidates = candidates[np.argsort(length[candidates])[:8]]
    best_phi, best_len = None, math.inf
    for k in candidates:
        phi = coarse[k]
        for half, n in ((math.radians(0.15), 121), (math.radians(0.003), 61)):
            fine = phi + np.linspace(-half, half, n)
            a, b = chords(poly, c, fine)
            L = b - a
            j = int(np.nanargmin(L))
            phi = float(fine[j])
        if L[j] < best_len:
            best_len, best_phi = float(L[j]), phi
    a, b = chords(poly, c, np.array([best_phi]))
    u = np.array([math.cos(best_phi), math.sin(best_phi)])
    return {"opening": best_len, "angle_deg": fold_axis_deg(math.degrees(best_phi)),
            "p1": (c + a[0] * u).tolist(), "p2": (c + b[0] * u).tolist()}


def describe(poly):
    """All the truth of one placed polygon (pixels)."""
    c = area_centroid(poly)
    mu20, mu11, mu02 = area_moments(poly)
    area_axis, aspect = principal_axis(mu20, mu11, mu02)
    sxx, sxy, syy = boundary_moments(poly)
    edge_axis, edge_ratio = principal_axis(sxx, sxy, syy)
    grip = grip_chord(poly, c)
    return {"centroid": c.tolist(), "area": area(poly), "orientation_deg": edge_axis,
            "orientation_area_deg": area_axis, "aspect": aspect, "boundary_ratio": edge_ratio, "grip": grip}
