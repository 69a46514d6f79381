"""markersim.py - renders a table seen from above through a pinhole camera at a given pose: ArUco markers (on their
white paper) and dark polygons at known positions in the arm's base frame (mm), for the workspace calibration's
simulation tests. Exact truth: every marker's centre and object's centroid is returned as placed.

The camera is set by its centre (base frame, mm), small rotations about the base axes (deg) applied to the nominal
straight-down orientation, and a focal length in pixels. The nominal one matches data/rbx1.toml's [arm.camera]
(origin (370, 100) mm, rotation -90, flip_y) at 40 px/cm for an 800 x 600 image: camera_nominal()."""
import math

import cv2
import numpy as np

CANVAS_PX_PER_MM = 8.0  # the table is drawn at this resolution, then projected at 2x and area-averaged


class Camera:
    def __init__(self, centre_mm, rot_deg=(0.0, 0.0, 0.0), focal_px=2000.0, size=(800, 600), principal=(400.0, 300.0)):
        self.size = size
        self.k = np.array([[focal_px, 0, principal[0]], [0, focal_px, principal[1]], [0, 0, 1]], float)
        # Nominal: image x along base -y, image y along base -x, optical axis down (rows: camera axes in base).
        r0 = np.array([[0, -1, 0], [-1, 0, 0], [0, 0, -1]], float)
        rx, ry, rz = (math.radians(a) for a in rot_deg)
        def rot(axis, a):
            c, s = math.cos(a), math.sin(a)
            m = {"x": [[1, 0, 0], [0, c, -s], [0, s, c]], "y": [[c, 0, s], [0, 1, 0], [-s, 0, c]],
                 "z": [[c, -s, 0], [s, c, 0], [0, 0, 1]]}[axis]
            return np.array(m, float)
        tilt = rot("z", rz) @ rot("y", ry) @ rot("x", rx)  # a rotation of the camera body in the base frame
        self.r = r0 @ tilt.T
        self.c = np.array(centre_mm, float)

    def table_to_image(self, table_z_mm=0.0):
        """3x3 homography: base-frame (x, y) mm on the plane z = table_z -> image pixels."""
        t = -self.r @ self.c
        m = np.column_stack([self.r[:, 0], self.r[:, 1], self.r[:, 2] * table_z_mm + t])
        return self.k @ m

    def project(self, x_mm, y_mm, table_z_mm=0.0):
        p = self.table_to_image(table_z_mm) @ np.array([x_mm, y_mm, 1.0])
        return p[0] / p[2], p[1] / p[2]


def camera_nominal(height_mm=500.0):
    """The camera that data/rbx1.toml's mount describes: 4 px/mm, pixel (0, 0) at base (370, 100) mm."""
    return Camera((295.0, 0.0, height_mm), (0, 0, 0), focal_px=4.0 * height_mm)


def render(camera, markers=(), objects=(), dictionary="4X4_50", extent_mm=((180, 420), (-150, 150)), table=200,
           table_z_mm=0.0):
    """markers: [(id, x_mm, y_mm, side_mm)], each on a white paper square 1.5 x its side; objects: [(polygon
    [(x_mm, y_mm), ...], gray)]. Returns (BGR image, truth) with truth = {"markers": {id: (x, y)}, "objects":
    [(cx, cy)]}: centres as drawn, exact to the canvas's sub-pixel placement."""
    (x0, x1), (y0, y1) = extent_mm
    s = CANVAS_PX_PER_MM
    w, h = int((y1 - y0) * s), int((x1 - x0) * s)
    canvas = np.full((h, w), table, np.uint8)
    # canvas pixel (col, row) centre <-> base (x1 - row / s, y1 - col / s)
    to_canvas = lambda x, y: ((y1 - y) * s, (x1 - x) * s)
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, "DICT_" + dictionary))
    truth = {"markers": {}, "objects": []}
    for mid, x, y, side in markers:
        n = int(round(side * s))
        paper = int(round(side * 1.5 * s))
        cu, cv_ = to_canvas(x, y)
        c0, r0 = int(round(cu - n / 2)), int(round(cv_ - n / 2))
        p0, q0 = int(round(cu - paper / 2)), int(round(cv_ - paper / 2))
        canvas[q0:q0 + paper, p0:p0 + paper] = 255
        canvas[r0:r0 + n, c0:c0 + n] = cv2.aruco.drawMarker(d, mid, n)
        # Pixels c0..c0+n-1 cover c0-0.5 .. c0+n-0.5: the drawn centre.
        truth["markers"][mid] = (x1 - (r0 + (n - 1) / 2) / s, y1 - (c0 + (n - 1) / 2) / s)
    for poly, gray in objects:
        pts = np.array([to_canvas(x, y) for x, y in poly]) * 16
        cv2.fillPoly(canvas, [np.round(pts).astype(np.int32)], int(gray), cv2.LINE_AA, shift=4)
        truth["objects"].append(tuple(np.mean(np.array(poly), axis=0)))
    # canvas pixel -> base mm -> image (2x supersampled) pixel.
    # a maps (col, row, 1) -> (x, y, 1): x = x1 - row / s, y = y1 - col / s.
    a = np.array([[0, -1 / s, x1], [-1 / s, 0, y1], [0, 0, 1]], float)
    sup = np.array([[2, 0, 0.5], [0, 2, 0.5], [0, 0, 1]], float)
    hmat = sup @ camera.table_to_image(table_z_mm) @ a
    big = cv2.warpPerspective(canvas, hmat, (camera.size[0] * 2, camera.size[1] * 2), flags=cv2.INTER_LINEAR,
                              borderValue=table)
    img = cv2.resize(big, camera.size, interpolation=cv2.INTER_AREA)
    return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR), truth


def rectangle(cx, cy, length, width, yaw_deg):
    """A rectangle's corners (base mm), its long side along yaw_deg from base +x."""
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    pts = []
    for u, v in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
        lx, ly = u * length / 2, v * width / 2
        pts.append((cx + c * lx - s * ly, cy + s * lx + c * ly))
    return pts
