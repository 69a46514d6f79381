"""render.py - anti-aliased rendering: exact area coverage of polygons, table backgrounds, light, shadows, blur
and sensor noise. Pixel (row i, column j) covers [j - 0.5, j + 0.5] x [i - 0.5, i + 0.5] (shared/DESIGN.md)."""
import math

import cv2
import numpy as np

SUBROWS = 16  # horizontal scanlines per pixel row; along each scanline the coverage is exact


def lit(img, gain, offset):
    """An 8-bit image under another light: each level * gain + offset, rounded and clipped to 0-255 (the light
    sweep's levels, issue 27)."""
    return np.clip(np.rint(img.astype(np.float64) * gain + offset), 0, 255).astype(np.uint8)


def coverage(poly, shape, subrows=SUBROWS):
    """Fraction of each pixel covered by the polygon (float64, shape (h, w)).

    The polygon is cut into horizontal bands at every 1/subrows of a pixel and at every vertex, so inside a band
    each boundary crossing moves linearly: the span at the band's middle times its height is the band's exact
    area, and along x the span's overlap with each pixel is exact."""
    h, w = shape
    out = np.zeros((h, w), np.float64)
    p = np.asarray(poly, float)
    q = np.roll(p, -1, axis=0)
    ylo, yhi = max(p[:, 1].min(), -0.5), min(p[:, 1].max(), h - 0.5)
    if ylo >= yhi:
        return out
    grid = (np.arange(math.floor((ylo + 0.5) * subrows), math.ceil((yhi + 0.5) * subrows) + 1)) / subrows - 0.5
    cuts = np.unique(np.concatenate([grid, p[:, 1]]))
    cuts = cuts[(cuts >= ylo) & (cuts <= yhi)]
    mids, heights = (cuts[:-1] + cuts[1:]) / 2, np.diff(cuts)
    keep = heights > 1e-12
    mids, heights = mids[keep], heights[keep]
    rows = np.clip(np.floor(mids + 0.5).astype(np.int64), 0, h - 1)

    y0, y1 = p[:, 1], q[:, 1]
    lo, hi = np.minimum(y0, y1), np.maximum(y0, y1)
    crosses = (mids[:, None] >= lo[None, :]) & (mids[:, None] < hi[None, :])
    with np.errstate(divide="ignore", invalid="ignore"):
        xs = p[None, :, 0] + (mids[:, None] - y0[None, :]) * ((q[:, 0] - p[:, 0]) / (y1 - y0))[None, :]
    xs = np.sort(np.where(crosses, xs, np.inf), axis=1)
    counts = crosses.sum(axis=1)
    diff = np.zeros((h, w + 1), np.float64)
    for m in range(0, int(counts.max(initial=0)) // 2):
        sel = counts >= 2 * m + 2
        # Interval [a, b] in image x; pixel j covers [j - 0.5, j + 0.5]: shift to u = x + 0.5.
        a = np.clip(xs[sel, 2 * m] + 0.5, 0.0, w)
        b = np.clip(xs[sel, 2 * m + 1] + 0.5, 0.0, w)
        r, wt = rows[sel], heights[sel]
        ok = b > a
        a, b, r, wt = a[ok], b[ok], r[ok], wt[ok]
        j0 = np.minimum(a.astype(np.int64), w - 1)
        j1 = b.astype(np.int64)
        same = j0 == j1
        np.add.at(out, (r[same], j0[same]), (b - a)[same] * wt[same])
        d = ~same
        np.add.at(out, (r[d], j0[d]), (j0[d] + 1 - a[d]) * wt[d])
        np.add.at(diff, (r[d], j0[d] + 1), wt[d])
        np.add.at(diff, (r[d], j1[d]), -wt[d])
        tail = d & (j1 < w)
        np.add.at(out, (r[tail], j1[tail]), (b[tail] - j1[tail]) * wt[tail])
    out += np.cumsum(diff, axis=1)[:, :w]
    return out


def lowpass_noise(rng, shape, cell):
    """Smooth random field in about [-1, 1] with features of `cell` pixels."""
    h, w = shape
    small = rng.standard_normal((max(2, h // cell + 2), max(2, w // cell + 2)))
    big = cv2.resize(small, (w + 2 * cell, h + 2 * cell), interpolation=cv2.INTER_CUBIC)
    big = big[cell:cell + h, cell:cell + w]
    return np.clip(big / 1.5, -1.0, 1.0)


def table(rng, shape, kind, level, amplitude):
    """A table surface (float, gray levels): uniform, or one of the patterns wood / cloth / blotches / tiles."""
    h, w = shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    if kind == "uniform":
        pattern = np.zeros(shape)
    elif kind == "wood":
        theta = rng.uniform(0, math.pi)
        period = rng.uniform(14, 30)
        along = xs * math.cos(theta) + ys * math.sin(theta)
        phase = 2.5 * lowpass_noise(rng, shape, 60)
        pattern = np.sin(2 * math.pi * along / period + phase) * (0.6 + 0.4 * lowpass_noise(rng, shape, 40))
    elif kind == "cloth":
        period = rng.uniform(5, 9)
        pattern = 0.5 * (np.sin(2 * math.pi * xs / period) + np.sin(2 * math.pi * ys / period))
    elif kind == "blotches":
        pattern = lowpass_noise(rng, shape, int(rng.uniform(15, 40)))
    elif kind == "tiles":
        size = int(rng.uniform(40, 90))
        pattern = np.where(((xs // size) + (ys // size)) % 2 == 0, 1.0, -1.0)
        pattern = cv2.GaussianBlur(pattern, (0, 0), 0.8)
    else:
        raise ValueError(f"unknown table kind {kind!r}")
    return level + amplitude * pattern


def illumination(rng, shape, strength):
    """Uneven light: a linear gradient and vignetting, multiplicative, about 1 +- strength."""
    h, w = shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    gx, gy = rng.uniform(-strength, strength, size=2)
    nx, ny = (xs - w / 2) / w, (ys - h / 2) / h
    vignette = rng.uniform(0, strength) * (nx * nx + ny * ny) * 2
    return (1.0 + gx * nx * 2 + gy * ny * 2) * (1.0 - vignette)


def shadow_mask(alpha, dx, dy, sigma):
    """Soft shadow of everything in alpha, cast by a light from the opposite direction of (dx, dy)."""
    m = np.float32([[1, 0, dx], [0, 1, dy]])
    shifted = cv2.warpAffine(alpha.astype(np.float32), m, (alpha.shape[1], alpha.shape[0]),
                             flags=cv2.INTER_LINEAR, borderValue=0)
    return cv2.GaussianBlur(shifted, (0, 0), sigma).astype(np.float64)


def finish(img_bgr, rng, blur_sigma, noise_sigma):
    """Camera: optical blur, then sensor noise, then 8-bit quantisation."""
    out = img_bgr
    if blur_sigma > 0:
        out = cv2.GaussianBlur(out, (0, 0), blur_sigma)
    if noise_sigma > 0:
        out = out + noise_sigma * rng.standard_normal(size=out.shape, dtype=np.float32)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
