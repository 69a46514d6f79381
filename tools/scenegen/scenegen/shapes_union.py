"""shapes_union.py - the narrow-part classes (a stem and leaf, prongs with balls, teeth, a handle, tentacles, an
open ring, a key) as one polygon each (cm): their simple parts filled at 400 px/cm and the union's outline
traced (vertices within 0.0015 cm of it). The polygon is the object: rendering and truth both use it exactly."""
import math

import cv2
import numpy as np

RES = 400.0  # px per cm of the tracing raster


def _ellipse(cx, cy, a, b, angle_deg=0.0, n=96):
    t = np.arange(n) * 2 * math.pi / n
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    x, y = a * np.cos(t), b * np.sin(t)
    return np.column_stack([cx + c * x - s * y, cy + s * x + c * y])


def _bar(p, q, width):
    """A rectangle of `width` from point p to point q (cm)."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    d = (q - p) / np.linalg.norm(q - p)
    n = np.array([-d[1], d[0]]) * width / 2
    return np.array([p + n, q + n, q - n, p - n])


def _polyline_band(points, width):
    """A band of `width` along a polyline, as one polygon (left side out, right side back)."""
    pts = np.asarray(points, float)
    left, right = [], []
    for i, p in enumerate(pts):
        a, b = pts[max(i - 1, 0)], pts[min(i + 1, len(pts) - 1)]
        d = (b - a) / np.linalg.norm(b - a)
        n = np.array([-d[1], d[0]]) * width / 2
        left.append(p + n)
        right.append(p - n)
    return np.array(left + right[::-1])


def union(parts):
    """The outline of the union of polygons (cm), traced at RES px/cm, as one polygon (cm)."""
    allp = np.vstack(parts)
    lo = allp.min(axis=0) - 0.1
    size = np.ceil((allp.max(axis=0) - lo + 0.1) * RES).astype(int)
    mask = np.zeros((size[1], size[0]), np.uint8)
    for p in parts:
        pix = np.round((p - lo) * RES * 16).astype(np.int32)  # 4 fractional bits
        cv2.fillPoly(mask, [pix], 255, cv2.LINE_8, 4)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(contours, key=cv2.contourArea)
    c = cv2.approxPolyDP(c, 0.6, True).reshape(-1, 2).astype(float)
    return c / RES + lo


def fruit_leaf():
    stem = _bar((0, -1.0), (0.05, -1.55), 0.12)
    leaf = _ellipse(0.5, -1.62, 0.55, 0.22, -15)
    return union([_ellipse(0, 0, 1.1, 1.1), stem, leaf])


def crown():
    parts = [np.array([[-1.5, 0], [1.5, 0], [1.5, 0.9], [-1.5, 0.9]], float)]
    for x, h in ((-1.3, 0.6), (-0.65, 0.75), (0.0, 0.9), (0.65, 0.75), (1.3, 0.6)):
        parts.append(_bar((x, 0.05), (x, -h), 0.16))
        parts.append(_ellipse(x, -h - 0.12, 0.2, 0.2))
    return union(parts)


def gear(teeth=12, r_root=1.1, r_tip=1.45):
    pts = []
    step = 2 * math.pi / teeth
    for k in range(teeth):
        t = k * step
        for dt, r in ((-0.30, r_root), (-0.17, r_tip), (0.17, r_tip), (0.30, r_root)):
            pts.append([r * math.cos(t + dt * step * 1.6), r * math.sin(t + dt * step * 1.6)])
    return np.array(pts, float)


def pan():
    grip = _ellipse(2.55, 0, 0.6, 0.25)
    return union([_ellipse(0, 0, 1.0, 1.0), _bar((0.9, 0), (2.1, 0), 0.22), grip])


def jellyfish():
    t = np.linspace(0, math.pi, 48)
    dome = np.column_stack([1.3 * np.cos(t), -0.9 * np.sin(t)])
    parts = [np.vstack([dome, [[-1.3, 0.1], [1.3, 0.1]]])]
    for x in (-1.0, -0.5, 0.0, 0.5, 1.0):
        y = np.linspace(0.0, 1.6, 24)
        parts.append(_polyline_band(np.column_stack([x + 0.12 * np.sin(y * 5), y]), 0.14))
        parts.append(_ellipse(x + 0.12 * math.sin(1.6 * 5), 1.68, 0.17, 0.17))
    return union(parts)


def c_ring(r_out=1.3, r_in=0.85, gap_deg=50.0, n=96):
    a0, a1 = math.radians(gap_deg / 2), 2 * math.pi - math.radians(gap_deg / 2)
    t = np.linspace(a0, a1, n)
    outer = np.column_stack([r_out * np.cos(t), r_out * np.sin(t)])
    inner = np.column_stack([r_in * np.cos(t[::-1]), r_in * np.sin(t[::-1])])
    return np.vstack([outer, inner])


def key():
    parts = [_ellipse(0, 0, 0.7, 0.7), _bar((0.6, 0), (2.8, 0), 0.3),
             _bar((2.2, 0.1), (2.2, 0.45), 0.2), _bar((2.6, 0.1), (2.6, 0.4), 0.2)]
    return union(parts)
