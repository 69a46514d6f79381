"""chessboard.py - chessboard views as a camera with known intrinsics and lens distortion sees them, for
`rbx1 calibrate` tests and demos. 2x2 supersampling of a prefiltered board texture: corners land where
cv2.projectPoints puts them to about 0.05 px."""
import cv2
import numpy as np

# The default camera: 640 x 480, barrel distortion strong enough to matter (tens of pixels in the corners).
CAMERA_MATRIX = np.array([[600.0, 0.0, 317.5], [0.0, 605.0, 242.25], [0.0, 0.0, 1.0]])
DIST_COEFFS = np.array([-0.21, 0.06, 0.0012, -0.0008, 0.0])
SIZE = (640, 480)
# Nine poses (rvec, tvec mm) of a 9x6 board of 20 mm squares: centred, in each corner, tilted.
POSES = [((0.0, 0.0, 0.0), (-80, -50, 330)), ((0.2, -0.2, 0.05), (-170, -110, 330)),
         ((-0.2, -0.2, -0.05), (-5, -110, 330)), ((0.2, 0.2, 0.05), (-170, 0, 330)),
         ((-0.2, 0.2, -0.05), (-15, -5, 330)), ((0.45, 0.0, 0.0), (-80, -50, 360)),
         ((0.0, 0.45, 0.2), (-80, -50, 360)), ((0.2, -0.3, 0.5), (-60, -80, 360)),
         ((-0.3, -0.1, -0.4), (-90, -30, 340))]


def _rays(k, dist, size):
    w, h = size
    u, v = np.meshgrid(np.arange(2 * w), np.arange(2 * h))
    px = np.stack([(u - 0.5) / 2, (v - 0.5) / 2], -1).reshape(-1, 1, 2).astype(np.float64)
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 40, 1e-12)
    return cv2.undistortPointsIter(px, k, dist, None, None, crit).reshape(-1, 2)


def _texture(inner, square_mm, tex_per_mm):
    sx, sy = inner[0] + 1, inner[1] + 1
    margin = square_mm
    tex = np.full((int((sy * square_mm + 2 * margin) * tex_per_mm), int((sx * square_mm + 2 * margin) * tex_per_mm)),
                  235, np.uint8)
    for r in range(sy):
        for c in range(sx):
            if (r + c) % 2 == 0:
                y0, y1 = int((margin + r * square_mm) * tex_per_mm), int((margin + (r + 1) * square_mm) * tex_per_mm)
                x0, x1 = int((margin + c * square_mm) * tex_per_mm), int((margin + (c + 1) * square_mm) * tex_per_mm)
                tex[y0:y1, x0:x1] = 25
    # Prefilter to the supersample footprint so point sampling does not alias the square edges.
    return cv2.GaussianBlur(tex, (0, 0), 4.0), -square_mm - margin


def render_views(k=CAMERA_MATRIX, dist=DIST_COEFFS, size=SIZE, poses=POSES, inner=(9, 6), square_mm=20.0,
                 noise=0.0, seed=0):
    """Gray uint8 views of the board (first inner corner at the board origin) in the given poses."""
    tex_per_mm = 8.0
    tex, origin = _texture(inner, square_mm, tex_per_mm)
    norm = _rays(k, dist, size)
    w, h = size
    rng = np.random.default_rng(seed)
    views = []
    for rvec, tvec in poses:
        rot, _ = cv2.Rodrigues(np.array(rvec, float))
        hbn = np.column_stack([rot[:, 0], rot[:, 1], np.array(tvec, float)])
        b = np.column_stack([norm, np.ones(len(norm))]) @ np.linalg.inv(hbn).T
        mx = ((b[:, 0] / b[:, 2] - origin) * tex_per_mm - 0.5).reshape(2 * h, 2 * w).astype(np.float32)
        my = ((b[:, 1] / b[:, 2] - origin) * tex_per_mm - 0.5).reshape(2 * h, 2 * w).astype(np.float32)
        hi = cv2.remap(tex, mx, my, cv2.INTER_LINEAR, borderValue=128)
        img = cv2.resize(hi.astype(np.float32), size, interpolation=cv2.INTER_AREA)
        if noise > 0:
            img = img + rng.normal(0, noise, img.shape)
        views.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    return views


def distort_pixels(undistorted_px, k=CAMERA_MATRIX, dist=DIST_COEFFS):
    """Where the lens puts points that an ideal (undistorted) camera with matrix k would see at undistorted_px."""
    p = np.asarray(undistorted_px, float)
    rays = np.column_stack([(p[:, 0] - k[0, 2]) / k[0, 0], (p[:, 1] - k[1, 2]) / k[1, 1], np.ones(len(p))])
    out, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), k, dist)
    return out.reshape(-1, 2)


def board_corners(rvec, tvec, inner=(9, 6), square_mm=20.0, k=CAMERA_MATRIX, dist=DIST_COEFFS):
    obj = np.array([[x * square_mm, y * square_mm, 0] for y in range(inner[1]) for x in range(inner[0])], float)
    out, _ = cv2.projectPoints(obj, np.array(rvec, float), np.array(tvec, float), k, dist)
    return out.reshape(-1, 2)
