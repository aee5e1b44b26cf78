"""Times stripecal.calibrate with and without the leave-one-view-out figure on twin
calibration folders of N views (BENCHMARKS.md, "Real cells (issue 12)" and "The
leave-one-out linear in the views (issue 41, item 5)").

    python scripts/bench_leave_one_out.py 15
    python scripts/bench_leave_one_out.py 15 60      # and the ratio of the two

With several N the folders are rendered first, then the calibrations run interleaved
(N1, N2, N1, N2, ...), best of --repeat each; CPU time of the process beside the wall
time. The hp3-paper twin, noise 1 gray level, PSF 0.7 px (bench_calibrate.py's), default
options otherwise (the board's stripe-bias correction on).

    python scripts/bench_leave_one_out.py 15 60 --cache /tmp/twins   # render once, reuse

--cache DIR keeps the rendered folders in DIR/N (rendered when absent), so that two
builds can be timed on the same folders (each run with its own PYTHONPATH).
"""
import argparse
import os
import tempfile
import time

import stripecal
import stripecal.sim

ap = argparse.ArgumentParser()
ap.add_argument("views", type=int, nargs="+")
ap.add_argument("--repeat", type=int, default=5)
ap.add_argument("--cache", metavar="DIR", help="keep the rendered folders in DIR/N")
a = ap.parse_args()
dirs = {}
for n in a.views:
    d = os.path.join(a.cache, str(n)) if a.cache else tempfile.mkdtemp()
    if a.cache and os.path.exists(os.path.join(d, "calib", "rig.json")):
        dirs[n] = d + "/calib"
        continue
    os.makedirs(d, exist_ok=True)
    cfg = stripecal.sim.preset(
        "hp3-paper",
        poses={"count": n},
        imaging={"noise_gray": 1.0, "psf_sigma_px": 0.7},
        scan={"enabled": False},
    )
    stripecal.sim.Twin(cfg).write(d)
    dirs[n] = d + "/calib"


def once(n, **kw):
    t0, c0 = time.perf_counter(), time.process_time()
    stripecal.calibrate(dirs[n], **kw)
    return time.perf_counter() - t0, time.process_time() - c0


best = {}
for _ in range(a.repeat):
    for n in a.views:
        for loo in (False, True):
            w, c = once(n, leave_one_out=loo)
            k = (n, loo)
            b = best.get(k, (1e9, 1e9))
            best[k] = (min(b[0], w), min(b[1], c))
print(f"best of {a.repeat}, interleaved; load {os.getloadavg()[0]:.2f}")
for n in a.views:
    (aw, ac), (bw, bc) = best[(n, False)], best[(n, True)]
    print(
        f"{n} views: calibrate without LOO {aw:.3f} s (cpu {ac:.3f}), with LOO {bw:.3f} s "
        f"(cpu {bc:.3f}), ratio {bw / aw:.2f}"
    )
if len(a.views) >= 2:
    n1, n2 = a.views[0], a.views[-1]
    (w1, c1), (w2, c2) = best[(n1, True)], best[(n2, True)]
    print(f"{n2} views / {n1} views with LOO: wall {w2 / w1:.2f}, cpu {c2 / c1:.2f} (linear: {n2 / n1:.1f})")
