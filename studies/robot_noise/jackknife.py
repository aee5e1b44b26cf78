#!/usr/bin/env python3
"""Split-half honesty with three sigmas side by side: the model's (calibration.json),
the delete-one-view jackknife's within each half (refits with the CLI), and their larger
one per number. Evidence for (or against) a per-view clustered covariance.

    STRIPECAL=... python studies/robot_noise/jackknife.py SET [-- OPTIONS]
"""
import csv, json, math, os, shutil, subprocess, sys, tempfile

STRIPECAL = os.environ.get("STRIPECAL", "stripecal")
KEYS = ("fu", "u0", "v0", "X tx", "X ty", "X tz")


def cal(folder, work, tag, rows, extra):
    d = os.path.join(work, tag)
    os.makedirs(d)
    shutil.copy(os.path.join(folder, "rig.json"), d)
    os.symlink(os.path.join(os.path.abspath(folder), "images"), os.path.join(d, "images"))
    with open(os.path.join(d, "views.csv"), "w", newline="") as f:
        csv.writer(f).writerows(rows)
    out = os.path.join(work, tag + ".json")
    r = subprocess.run([STRIPECAL, "calibrate", d, "-o", out, "--no-leave-one-out"] + extra, capture_output=True, text=True)
    if r.returncode != 0:
        return None
    c = json.load(open(out))
    u = c["uncertainty"]
    v = {k: (c["camera"][k], u["camera"][k]) for k in ("fu", "u0", "v0")}
    for k, a in enumerate("xyz"):
        v["X t" + a] = (c["hand_cam"]["translation_mm"][k], u["hand_cam"]["translation_mm"][k])
    return v


def main(argv):
    extra = []
    if "--" in argv:
        i = argv.index("--")
        argv, extra = argv[:i], argv[i + 1:]
    folder = argv[0]
    with open(os.path.join(folder, "views.csv"), newline="") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], rows[1:]
    work = tempfile.mkdtemp()
    try:
        halves = []
        for p in (0, 1):
            mine = [r for i, r in enumerate(body) if i % 2 == p]
            full = cal(folder, work, "h%d" % p, [head] + mine, extra)
            jk = [cal(folder, work, "h%d_%d" % (p, k), [head] + mine[:k] + mine[k + 1:], extra) for k in range(len(mine))]
            jk = [j for j in jk if j]
            n = len(jk)
            sj = {}
            for key in KEYS:
                xs = [j[key][0] for j in jk]
                m = sum(xs) / n
                sj[key] = math.sqrt((n - 1) / n * sum((x - m) ** 2 for x in xs))
            halves.append((full, sj))
        (a, ja), (b, jb) = halves
        zz = {"model": [], "jack": [], "max": []}
        for k in KEYS:
            d = a[k][0] - b[k][0]
            zm = d / math.hypot(a[k][1], b[k][1])
            zj = d / math.hypot(ja[k], jb[k])
            zx = d / math.hypot(max(a[k][1], ja[k]), max(b[k][1], jb[k]))
            for t, z in (("model", zm), ("jack", zj), ("max", zx)):
                zz[t].append(z)
            print("%-5s diff %+8.3f  model sig %.3f/%.3f  jack sig %.3f/%.3f  z model %+.2f jack %+.2f max %+.2f" % (
                k, d, a[k][1], b[k][1], ja[k], jb[k], zm, zj, zx))
        print("RMS z: " + "  ".join("%s %.2f" % (t, math.sqrt(sum(z * z for z in v) / len(v))) for t, v in zz.items()))
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main(sys.argv[1:])
