"""Times stripecal.calibrate with and without the leave-one-view-out figure on a twin
calibration folder of N views (BENCHMARKS.md, "Real cells (issue 12)").

    python scripts/bench_leave_one_out.py 15
"""
import time, sys, tempfile, stripecal, stripecal.sim, statistics
d = tempfile.mkdtemp()
tw = stripecal.sim.Twin(stripecal.sim.preset("hp3-paper", {"scan": {"enabled": False}, "poses": {"count": int(sys.argv[1])}}))
tw.write(d)
def t(**kw):
    ts = []
    for _ in range(5):
        t0 = time.perf_counter(); stripecal.calibrate(d + "/calib", **kw); ts.append(time.perf_counter() - t0)
    return statistics.median(ts)
a = t(leave_one_out=False); b = t()
print(f"{sys.argv[1]} views: calibrate without LOO {a:.3f} s, with LOO {b:.3f} s, ratio {b/a:.2f}")
