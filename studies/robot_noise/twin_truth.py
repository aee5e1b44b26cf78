#!/usr/bin/env python3
"""A twin's calibration against its truth: z = (estimate - truth) / stated sigma of the
camera (fu, fv, u0, v0), the plane's d, hand-eye X and robot-world Z (rotation vector and
translation), and the robot-pose noise.

    stripecal simulate OUT --no-scan --poses 15 [--set ...]
    STRIPECAL=... python studies/robot_noise/twin_truth.py OUT/calib [-- OPTIONS]
"""
import json, math, os, subprocess, sys, tempfile
import numpy as np

STRIPECAL = os.environ.get("STRIPECAL", "stripecal")


def rv_branch(r, ref):
    r = np.asarray(r, float)
    if np.linalg.norm(r - ref) > math.pi:
        r = r * (1 - 2 * math.pi / np.linalg.norm(r))
    return r


def main(argv):
    extra = []
    if "--" in argv:
        i = argv.index("--")
        argv, extra = argv[:i], argv[i + 1:]
    folder = argv[0]
    truth = json.load(open(os.path.join(folder, "truth.json")))
    with tempfile.TemporaryDirectory() as d:
        out = os.path.join(d, "c.json")
        r = subprocess.run([STRIPECAL, "calibrate", folder, "-o", out, "--no-leave-one-out"] + extra, capture_output=True, text=True)
        if r.returncode:
            print("FAILED", r.stderr[-500:])
            return
        c = json.load(open(out))
    u = c["uncertainty"]
    zs = []
    line = []
    for k in ("fu", "fv", "u0", "v0"):
        z = (c["camera"][k] - truth["camera"][k]) / u["camera"][k]
        zs.append(z)
        line.append("%s %+.1f" % (k, z))
    if c.get("laser_plane"):
        z = (c["laser_plane"]["d_mm"] - truth["laser_plane"]["d_mm"]) / u["laser_plane"]["d_mm"]
        zs.append(z)
        line.append("d %+.1f" % z)
    for key, name in (("hand_cam", "X"), ("base_board", "Z")):
        tr = np.asarray(truth[key]["rotation_vector"])
        er = rv_branch(c[key]["rotation_vector"], tr)
        for k in range(3):
            z = (er[k] - tr[k]) / u[key]["rotation_vector"][k]
            zs.append(z)
            line.append("%sr%d %+.1f" % (name, k, z))
        for k in range(3):
            z = (c[key]["translation_mm"][k] - truth[key]["translation_mm"][k]) / u[key]["translation_mm"][k]
            zs.append(z)
            line.append("%st%d %+.1f" % (name, k, z))
    rn = c.get("robot_pose_noise")
    noise = "noise %.4g mm %.4g deg" % (rn["translation_mm"], rn["rotation_deg"]) if rn else "no pose noise"
    print("%s | max |z| %.1f RMS z %.2f | %s" % (noise, max(abs(z) for z in zs), math.sqrt(np.mean(np.square(zs))), " ".join(line)))


if __name__ == "__main__":
    main(sys.argv[1:])
