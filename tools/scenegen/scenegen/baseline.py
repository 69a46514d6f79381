"""baseline.py - a plain OpenCV pipeline measured on the same scenes, as the accuracy benchmark's baseline:
background difference, Otsu threshold, connected components; centroid and axis from the binary moments,
grip opening from minAreaRect's short side."""
import math

import cv2
import numpy as np

from .truth import fold_axis_deg


def detect(image_bgr, background_bgr, min_area=40):
    g = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2GRAY).astype(np.int16)
    b = cv2.cvtColor(background_bgr, cv2.COLOR_BGR2GRAY).astype(np.int16)
    diff = np.abs(g - b).astype(np.uint8)
    _, mask = cv2.threshold(diff, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    n, labels, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    h, w = mask.shape
    out = []
    for k in range(1, n):
        x, y, bw, bh, area = stats[k]
        if area < min_area or x == 0 or y == 0 or x + bw >= w or y + bh >= h:
            continue
        comp = (labels[y:y + bh, x:x + bw] == k).astype(np.uint8)
        m = cv2.moments(comp, binaryImage=True)
        axis = fold_axis_deg(math.degrees(0.5 * math.atan2(2 * m["mu11"], m["mu20"] - m["mu02"])))
        pts = np.column_stack(np.nonzero(comp)[::-1]).astype(np.float32)
        (_, _), (rw, rh), _ = cv2.minAreaRect(pts)
        # Pixel centres span one pixel less than the object: add it back.
        out.append({"centroid_px": [float(cents[k][0]), float(cents[k][1])], "orientation_deg": axis,
                    "grip": {"opening_px": float(min(rw, rh) + 1.0)}, "label": None})
    return out
