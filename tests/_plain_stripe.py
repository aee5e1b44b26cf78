"""A plain laser-line extractor, independent of stripecal's (DECISIONS 8): the points a
peer's multi-stage recipe would use, so that a held-out laser->board figure cannot be
improved by dropping hard points.

Per scan line (an image row for a line running along the columns): a morphological
top-hat across the line (a flat structuring element of TOPHAT_WIDTH px, wider than the
line), one intensity centroid over the run through the top-hat's maximum above half of
it; then the dominant straight line through the centroids (RANSAC, a TOL_PX band): the
line on the board's sheet up to its depth step, where the line jumps sideways and the
points drop out. The same extractor as studies/opencv_laser_recipe (which reproduces the
OpenCV figures of shared/realdata/README.md with it).
"""

from __future__ import annotations

from typing import Tuple

import cv2
import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]

TOPHAT_WIDTH = 61
"""px across the line: wider than a saturated line's base (30-40 px on the etna sets)."""
MIN_PEAK = 30.0
"""A scan line whose top-hat maximum is below this holds no line (gray levels)."""
REL_THRESHOLD = 0.5
"""The centroid's run: the top-hat above this fraction of the line's maximum."""
TOL_PX = 3.0
"""Inlier band around the dominant straight line, px."""
RANSAC_ITERS = 2000


def plain_extract(gray: npt.NDArray[np.uint8], direction: str = "cols") -> F64:
    """The kept points `(N, 2)` of one 8-bit gray image as `(u, v)` px (u = column)."""
    img = gray if direction == "cols" else gray.T
    se = cv2.getStructuringElement(cv2.MORPH_RECT, (TOPHAT_WIDTH, 1))
    th = cv2.morphologyEx(img, cv2.MORPH_TOPHAT, se).astype(np.float64)
    scan, pos = [], []
    for v in range(th.shape[0]):
        t = th[v]
        k = int(np.argmax(t))
        m = t[k]
        if m < MIN_PEAK:
            continue
        above = t > REL_THRESHOLD * m
        a, b = k, k + 1
        while a > 0 and above[a - 1]:
            a -= 1
        while b < len(t) and above[b]:
            b += 1
        w = t[a:b]
        scan.append(float(v))
        pos.append(float(np.sum(np.arange(a, b) * w) / np.sum(w)))
    if not scan:
        return np.zeros((0, 2))
    pts = np.stack([np.asarray(pos), np.asarray(scan)], axis=1)
    keep = _dominant_line(pts)
    uv = pts[keep]
    return uv if direction == "cols" else uv[:, ::-1].copy()


def _dominant_line(pts: F64) -> npt.NDArray[np.bool_]:
    """RANSAC on point pairs (the most points within TOL_PX), then two total-least-squares
    refits on the inliers."""
    n_pts = len(pts)
    if n_pts < 2:
        return np.zeros(n_pts, bool)
    rng = np.random.default_rng(0)
    best = np.zeros(n_pts, bool)
    for _ in range(RANSAC_ITERS):
        i, j = rng.choice(n_pts, 2, replace=False)
        d = pts[j] - pts[i]
        length = float(np.hypot(d[0], d[1]))
        if length < 1e-9:
            continue
        n = np.array([-d[1], d[0]]) / length
        inl = np.abs(pts @ n - n @ pts[i]) < TOL_PX
        if inl.sum() > best.sum():
            best = inl
    keep = best
    for _ in range(2):
        n, c = _tls_line(pts[keep])
        keep = np.abs(pts @ n - c) < TOL_PX
    return keep


def _tls_line(p: F64) -> Tuple[F64, float]:
    m = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - m, full_matrices=False)
    n: F64 = vt[-1]
    return n, float(n @ m)
