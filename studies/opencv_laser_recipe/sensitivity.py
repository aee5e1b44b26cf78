#!/usr/bin/env python3
"""How much the held-out laser->board figure of recipe.py moves with the choices a peer
could have made differently (to explain the gap to the figures in
../shared/realdata/README.md). Each fold's camera and board poses are computed once;
the variants change only the stripe points, the laser plane's fit or the hand-eye.

Run:  python3 sensitivity.py            (both data sets; a few minutes)
"""

from __future__ import annotations

import sys
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

import recipe as R


def ls_translation(A: List[np.ndarray], B: List[np.ndarray], RX: np.ndarray, RZ: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """t_X, t_Z by linear least squares of A_i X B_i = Z's translation in the BASE frame,
    R_A t_X - t_Z = -t_A - R_A R_X t_B, with the rotations fixed (PARK's)."""
    M, b = [], []
    for a, bb in zip(A, B):
        m = np.zeros((3, 6))
        m[:, :3] = a[:3, :3]
        m[:, 3:] = -np.eye(3)
        M.append(m)
        b.append(-a[:3, 3] - a[:3, :3] @ RX @ bb[:3, 3])
    s = np.linalg.lstsq(np.vstack(M), np.concatenate(b), rcond=None)[0]
    return R.make(RX, s[:3]), R.make(RZ, s[3:])


def fit_plane_on_chain(c: R.Calib, views: List[R.View], method: str) -> Tuple[np.ndarray, float]:
    """The laser plane fitted on the board planes the chain predicts, (A_i X)^-1 Z,
    instead of each view's own solvePnP pose."""
    saved = c.B
    c.B = [R.inv(v.A @ c.X[method]) @ c.Z[method] for v in views]
    plane, _, _ = R.fit_laser_plane(c, views)
    c.B = saved
    return plane


def run(name: str) -> None:
    ds = R.load(name)
    model = ds.rig["camera"]["distortion_model"]
    base_tol = R.RANSAC_TOL_PX
    stripes: Dict[float, List[R.Stripe]] = {}

    def set_points(tol: float, restrict: Optional[Callable[[R.View], None]] = None) -> Tuple[int, int]:
        if tol not in stripes:
            stripes[tol] = [R.plain_extract(v.gray, "cols", tol) for v in ds.views]
        for v, s in zip(ds.views, stripes[tol]):
            v.stripe = R.Stripe(**{**s.__dict__, "keep": s.keep.copy()})  # restrict a copy
            if restrict:
                restrict(v)
        k = [int(v.stripe.keep.sum()) for v in ds.views]
        return min(k), max(k)

    set_points(base_tol)
    folds = []
    for held in ds.views:
        train = [v for v in ds.with_board() if v is not held]
        c = R.calibrate(ds, train, model)
        X, Z = ls_translation([v.A for v in train], c.B, c.X["PARK"][:3, :3], c.Z["PARK"][:3, :3])
        c.X["PARK+LS"], c.Z["PARK+LS"] = X, Z
        folds.append((held, train, c))

    def figure(method: str = "PARK", plane_on_chain: bool = False) -> Tuple[float, float, float]:
        d, chain = [], []
        for held, train, c in folds:
            c.plane = fit_plane_on_chain(c, train, method) if plane_on_chain else R.fit_laser_plane(c, train)[0]
            d.append(R.laser_to_board(c, method, held))
            if held.corners is not None:
                chain.append(R.chain_error(ds, c, method, held)[0])
        a = np.abs(np.concatenate(d))
        return float(np.median(chain)), float(np.median(a)), float(np.percentile(a, 95))

    def board_rows(v: R.View) -> None:
        if v.corners is not None:
            lo, hi = v.corners[:, 1].min(), v.corners[:, 1].max()
            v.stripe.keep &= (v.stripe.scan >= lo) & (v.stripe.scan <= hi)

    print(f"\n=== {name}: variant | plain points min-max | chain median px | laser->board median, p95 mm")
    rows = []
    for tol in (1.0, 2.0, 3.0, 5.0):
        mm = set_points(tol)
        rows.append((f"RANSAC tol {tol:g} px, PARK", mm, figure("PARK")))
    mm = set_points(base_tol, board_rows)
    rows.append(("tol 3, only rows spanned by the printed corners, PARK", mm, figure("PARK")))
    mm = set_points(base_tol)
    rows.append(("tol 3, plane fitted on the chain-predicted board planes, PARK", mm, figure("PARK", True)))
    rows.append(("tol 3, SHAH (OpenCV)", mm, figure("SHAH")))
    rows.append(("tol 3, PARK rotations + base-frame LS translations", mm, figure("PARK+LS")))
    # a different corner refinement window moves the camera and every board pose
    saved = R.SUBPIX_WIN
    R.SUBPIX_WIN = (11, 11)
    for v in ds.views:
        v.corners, _ = R.detect_chessboard(v.gray, int(ds.rig["board"]["rows"]), int(ds.rig["board"]["cols"]))
    R.SUBPIX_WIN = saved
    folds.clear()
    for held in ds.views:
        train = [v for v in ds.with_board() if v is not held]
        folds.append((held, train, R.calibrate(ds, train, model)))
    rows.append(("tol 3, cornerSubPix window 11 x 11 (instead of 5 x 5), PARK", mm, figure("PARK")))
    for label, (lo, hi), (ch, med, p95) in rows:
        print(f"{label:<64} {lo:>4}-{hi:<4} {ch:7.2f} {med:7.3f} {p95:7.3f}")


def main() -> int:
    for name in sys.argv[1:] or R.DATASETS:
        run(name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
