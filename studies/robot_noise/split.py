#!/usr/bin/env python3
"""Split-half honesty like ../../../shared/tools/split_half.py, but over every number both
halves report a sigma for (camera-only `--method paper` runs have no hand-eye sigma), and
printing the values and sigmas, not only z. Also the z of a third run's numbers against
a camera-only run: `--vs-paper` (acceptance 3: one-stage vs camera-only intrinsics).

    STRIPECAL=/work/venv-robot/bin/stripecal python studies/robot_noise/split.py SET [--vs-paper] [-- OPTIONS]
"""
import csv, json, math, os, shutil, subprocess, sys, tempfile

STRIPECAL = os.environ.get("STRIPECAL", "stripecal")


def run(folder, work, tag, extra, parity=None):
    d = os.path.join(work, tag)
    os.makedirs(d)
    shutil.copy(os.path.join(folder, "rig.json"), d)
    os.symlink(os.path.join(os.path.abspath(folder), "images"), os.path.join(d, "images"))
    with open(os.path.join(folder, "views.csv"), newline="") as f:
        rows = list(csv.reader(f))
    with open(os.path.join(d, "views.csv"), "w", newline="") as f:
        keep = [r for i, r in enumerate(rows[1:]) if parity is None or i % 2 == parity]
        csv.writer(f).writerows([rows[0]] + keep)
    out = os.path.join(work, tag + ".json")
    r = subprocess.run([STRIPECAL, "calibrate", d, "-o", out, "--no-leave-one-out"] + extra,
                       capture_output=True, text=True)
    if r.returncode != 0 or not os.path.exists(out):
        sys.exit("%s failed: %s" % (tag, r.stderr[-600:]))
    return json.load(open(out))


def values(c):
    u = c["uncertainty"]
    v = {}
    if "camera" in u:
        for k in ("fu", "fv", "u0", "v0"):
            v[k] = (c["camera"][k], u["camera"][k])
    if u.get("hand_cam"):
        for k, a in enumerate("xyz"):
            v["X t" + a] = (c["hand_cam"]["translation_mm"][k], u["hand_cam"]["translation_mm"][k])
    if c.get("laser_plane") and "d_mm" in u.get("laser_plane", {}):
        v["plane d"] = (c["laser_plane"]["d_mm"], u["laser_plane"]["d_mm"])
    return v


def main(argv):
    extra = []
    if "--" in argv:
        i = argv.index("--")
        argv, extra = argv[:i], argv[i + 1:]
    folder = argv[0]
    work = tempfile.mkdtemp()
    try:
        if "--vs-paper" in argv:
            a = values(run(folder, work, "one", extra))
            b = values(run(folder, work, "paper", ["--method", "paper", "--accept-poor"] + [e for e in extra if e != "--robot-pose-noise" and e != "--no-robot-pose-noise"]))
            for k in ("fu", "fv", "u0", "v0"):
                (x, sx), (y, sy) = a[k], b[k]
                print("%-4s one-stage %.2f +- %.2f  camera-only %.2f +- %.2f  z %+.2f  sigma ratio %.2f" % (
                    k, x, sx, y, sy, (x - y) / math.hypot(sx, sy), sx / sy))
            return
        a, b = values(run(folder, work, "h0", extra, 0)), values(run(folder, work, "h1", extra, 1))
        zs = []
        for k in a:
            if k in b:
                (x, sx), (y, sy) = a[k], b[k]
                z = (x - y) / math.hypot(sx, sy)
                zs.append(z)
                print("%-6s %.3f +- %.3f | %.3f +- %.3f | z %+.2f" % (k, x, sx, y, sy, z))
        print("RMS z %.2f" % math.sqrt(sum(z * z for z in zs) / len(zs)))
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main(sys.argv[1:])
