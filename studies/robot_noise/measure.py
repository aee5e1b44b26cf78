#!/usr/bin/env python3
"""One calibration per (data set, options) with the CLI: the held-out chain error
(DECISIONS 3), intrinsics with sigmas, hand-eye translation sigma, the robot-pose noise,
and, with --split, the split-half honesty figure (../../../shared/tools/split_half.py).

    STRIPECAL=/work/venv-robot/bin/stripecal python studies/robot_noise/measure.py \
        [--split] [--no-loo] SET [SET ...] [-- CALIBRATE OPTIONS]

SET is a folder (e.g. ../shared/realdata/rosi_10x10). Prints one line per set.
"""
import json
import os
import subprocess
import sys
import tempfile

STRIPECAL = os.environ.get("STRIPECAL", "stripecal")
HERE = os.path.dirname(os.path.abspath(__file__))
SPLIT = os.path.join(HERE, "..", "..", "..", "shared", "tools", "split_half.py")


def main(argv):
    extra = []
    if "--" in argv:
        i = argv.index("--")
        argv, extra = argv[:i], argv[i + 1:]
    split = "--split" in argv
    loo = "--no-loo" not in argv
    sets = [a for a in argv if not a.startswith("--")]
    for s in sets:
        name = os.path.basename(os.path.normpath(s))
        with tempfile.TemporaryDirectory() as d:
            out = os.path.join(d, "cal.json")
            cmd = [STRIPECAL, "calibrate", s, "-o", out] + extra + ([] if loo else ["--no-leave-one-out"])
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0 or not os.path.exists(out):
                print("%-14s FAILED exit %d: %s" % (name, r.returncode, (r.stderr.strip().splitlines() or [""])[-1][:300]))
                for l in r.stderr.strip().splitlines()[-6:]:
                    print("     ", l[:400])
            else:
                c = json.load(open(out))
                u = c["uncertainty"]
                cam = c["camera"]
                line = "%-14s fu %.1f+-%.2f u0 %.1f+-%.2f v0 %.1f+-%.2f" % (
                    name, cam["fu"], u["camera"]["fu"], cam["u0"], u["camera"]["u0"], cam["v0"], u["camera"]["v0"])
                line += " Xt_sig %s" % ",".join("%.2f" % x for x in u["hand_cam"]["translation_mm"])
                rn = c.get("robot_pose_noise")
                if rn:
                    line += " | noise %.3g mm %.3g deg" % (rn["translation_mm"], rn["rotation_deg"])
                    flagged = [v["view"] for v in rn.get("views", []) if v.get("test") is not None and v["test"] > 4]
                    if flagged:
                        line += " flagged %s" % flagged
                bs = c.get("board_scale")
                if bs:
                    line += " | scale %.4f+-%.4f" % (bs["scale"], bs["sigma"])
                lo = c.get("leave_one_out")
                if lo:
                    line += " | LOO %.3f px %.3f mm" % (lo["median_board_rms_px"], lo["median_board_rms_mm"])
                    if lo.get("median_stripe_rms_mm") is not None:
                        line += " stripe %.3f mm" % lo["median_stripe_rms_mm"]
                left = [v["view"] for v in c.get("views", []) if not v["used"]]
                if left:
                    line += " | left out %s" % left
                print(line)
                for w in c.get("warnings", []):
                    if "board scale" in w or "robot" in w:
                        print("      warning:", w[:300])
        if split:
            r = subprocess.run([sys.executable, SPLIT, s, "--"] + extra + ["--no-leave-one-out"],
                               capture_output=True, text=True, env=dict(os.environ, STRIPECAL=STRIPECAL))
            print("   split-half:", r.stdout.strip(), r.stderr.strip()[-300:])
        sys.stdout.flush()


if __name__ == "__main__":
    main(sys.argv[1:])
