"""The numpy peer of stripe extraction (issue 41, acceptance 3): per row, the brightest
pixel (``argmax``) and the 3-point centroid about it, vectorised over the whole frame, one
thread. Times it on the ``.npy`` frames of a folder (cycled) by the CPU time of the
thread (``time.thread_time_ns``), in slices of 0.25 s, and prints ``min median`` us per
frame. Run by ``cargo run --release -p stripecal-benches --example stripe_prof -- peer
PYTHON PAIRS SECONDS``, which writes the twin's scan frames and alternates this with
stripecal's extractor (BENCHMARKS.md, "Vision: stripes").

    python scripts/bench_stripe_numpy.py FOLDER [SECONDS [cols|rows]]

(``rows``: the line runs along the rows, each column is a scan line: the frames are
transposed once before timing, so the peer reads rows either way.)
"""

from __future__ import annotations

import os

# one thread, as stripecal's extractor (numpy's argmax does not thread; this keeps BLAS
# and friends from starting pools)
for _k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_k, "1")

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import numpy.typing as npt  # noqa: E402


def argmax_centroid(img: npt.NDArray[np.uint8]) -> npt.NDArray[np.float64]:
    """Per row: the column of the brightest pixel refined by the centroid of it and its
    two neighbours (``u = k + (I[k+1] - I[k-1]) / (I[k-1] + I[k] + I[k+1])``)."""
    h, w = img.shape
    k = np.clip(img.argmax(axis=1), 1, w - 2)
    r = np.arange(h)
    a = img[r, k - 1].astype(np.float32)
    b = img[r, k].astype(np.float32)
    c = img[r, k + 1].astype(np.float32)
    s = np.maximum(a + b + c, 1.0)
    u: npt.NDArray[np.float64] = k + (c - a) / s  # (int64 + float32: float64)
    return u


def main() -> None:
    folder = Path(sys.argv[1])
    secs = float(sys.argv[2]) if len(sys.argv) > 2 else 1.0
    frames = [np.load(p) for p in sorted(folder.glob("*.npy"))]
    if len(sys.argv) > 3 and sys.argv[3] == "rows":
        frames = [np.ascontiguousarray(f.T) for f in frames]
    for f in frames:
        argmax_centroid(f)
    times = []
    for _ in range(max(1, int(round(secs / 0.25)))):
        t0 = time.thread_time_ns()
        n = 0
        while time.thread_time_ns() - t0 < 250_000_000:
            for f in frames:
                argmax_centroid(f)
            n += len(frames)
        times.append((time.thread_time_ns() - t0) / n / 1e3)
    times.sort()
    print(f"{times[0]:.2f} {times[len(times) // 2]:.2f}")


if __name__ == "__main__":
    main()
