#!/usr/bin/env python3
"""Chessboard detection per image, stripecal against OpenCV on the same images, one
thread (issue 41, acceptance 2).

Cases (the images are made or read once, then timed):
- ``twin``: the ``hp3-chessboard`` twin (7 x 10 inner corners, 768 x 576), view 0;
- ``visp``: ``visp_franka`` (9 x 6, 640 x 480, 8 photographs) from ``--realdata``;
- ``big``: a 28 x 17 board at 1928 x 1208, the same twin with a larger sensor and
  3 mm squares (about 35 px), view 0.

Peer: ``cv2.findChessboardCorners(gray, (cols, rows))`` (default flags) followed by
``cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), (EPS + MAX_ITER, 100, 1e-4))``
(the settings of tests/test_realdata_targets.py), with ``cv2.setNumThreads(1)``.
Ours: ``stripecal.detect_target(gray, board)`` (single-threaded). Rounds interleave
the two; each round times every image of a case ``--reps`` times; the best round is
reported, per image, as CPU time of the process (``time.process_time``: the binding
runs the detection on a thread of its own, still one at a time) and wall time; under
load compare the CPU times.

Run: ``python scripts/bench_chessboard.py [--rounds 7] [--reps 3] [--cases twin,visp,big]
[--realdata ../shared/realdata]`` (needs the package built, release profile, and
opencv-python: the test extras).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import Callable, Dict, List, Tuple

import cv2
import numpy as np

import stripecal
import stripecal.sim as sim

BIG = {
    "camera": {"width": 1928, "height": 1208, "u0": 964.0, "v0": 604.0},
    "board": {"rows": 17, "cols": 28, "pitch_mm": 3.0, "square_mm": 3.0},
}


def twin_case(overrides: Dict) -> Tuple[List[np.ndarray], stripecal.Board]:
    cfg = sim.preset("hp3-chessboard", overrides)
    twin = sim.Twin(cfg)
    q = twin.calibration_poses()[0]["q_deg"]
    img = np.ascontiguousarray(twin.render_view(q, 0)["board_image"])
    b = cfg["board"]
    return [img], stripecal.Board.chessboard(b["rows"], b["cols"], b["square_mm"])


def visp_case(root: Path) -> Tuple[List[np.ndarray], stripecal.Board]:
    d = root / "visp_franka"
    imgs = [cv2.imread(str(d / "images" / f"franka_image-{k}.png"), cv2.IMREAD_GRAYSCALE) for k in range(1, 9)]
    return imgs, stripecal.Board.chessboard(6, 9, 23.6)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--cases", default="twin,visp,big")
    # the repository's sibling ../shared/realdata, as the tests
    ap.add_argument("--realdata", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "realdata"))
    a = ap.parse_args()
    cv2.setNumThreads(1)
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)

    cases: Dict[str, Tuple[List[np.ndarray], stripecal.Board]] = {}
    for name in a.cases.split(","):
        if name == "twin":
            cases[name] = twin_case({})
        elif name == "big":
            cases[name] = twin_case(BIG)
        elif name == "visp":
            if (Path(a.realdata) / "visp_franka").is_dir():
                cases[name] = visp_case(Path(a.realdata))
            else:
                print(f"visp: {a.realdata}/visp_franka not found, skipped")
        else:
            raise SystemExit(f"unknown case {name}")

    def ours(img: np.ndarray, board: stripecal.Board) -> int:
        return len(stripecal.detect_target(img, board))

    def opencv(img: np.ndarray, board: stripecal.Board) -> int:
        ok, c = cv2.findChessboardCorners(img, (board.cols, board.rows))
        if not ok:
            return 0
        return len(cv2.cornerSubPix(img, c, (5, 5), (-1, -1), crit))

    peers: Dict[str, Callable[[np.ndarray, stripecal.Board], int]] = {"stripecal": ours, "opencv": opencv}
    print(f"load average before: {os.getloadavg()[0]:.2f}; cv2 {cv2.__version__}, one thread")
    for name, (imgs, board) in cases.items():
        counts = {k: sum(f(i, board) for i in imgs) for k, f in peers.items()}
        best = {k: (np.inf, np.inf) for k in peers}
        for _ in range(a.rounds):
            for k, f in peers.items():
                c0, w0 = time.process_time(), time.perf_counter()
                for _ in range(a.reps):
                    for i in imgs:
                        f(i, board)
                n = a.reps * len(imgs)
                cpu, wall = (time.process_time() - c0) / n * 1e3, (time.perf_counter() - w0) / n * 1e3
                best[k] = (min(best[k][0], cpu), min(best[k][1], wall))
        h, w = imgs[0].shape[:2]
        o, p = best["stripecal"], best["opencv"]
        print(
            f"{name:5} {len(imgs)} image(s) {w}x{h}, corners ours {counts['stripecal']} / opencv {counts['opencv']}: "
            f"stripecal {o[0]:7.2f} ms cpu ({o[1]:7.2f} wall), opencv {p[0]:6.2f} ms cpu ({p[1]:6.2f} wall); "
            f"ours / opencv {o[0] / p[0]:5.2f}x cpu"
        )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
