"""The ``stripecal`` command-line interface.

Each subcommand is one ``cmd_<name>(args) -> int`` function plus one ``_add_<name>``
function that declares its arguments; ``build_parser`` lists the ``_add_`` functions.
To add a subcommand, write both and append the ``_add_`` function to ``_SUBCOMMANDS``.
The CLI only parses arguments, calls the library and prints: no numerics here.
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import platform
import signal
import sys
import tempfile
import threading
import time
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, cast

import numpy as np

import stripecal
import stripecal.sim
from stripecal._progress import Progress
from stripecal.cli_profiler import print_profiler_calibration
from stripecal.cli_measure import add_measure, load_any_calibration, add_verify, diameter_range, sphere_lines, write_json_atomic
from stripecal.types import QualityCheck, SimConfig, SphereMeasurement, TwinSummary


def cmd_info(args: argparse.Namespace) -> int:
    """Prints the version (and with --verbose, where things come from)."""
    print(f"stripecal {stripecal.__version__}")
    if args.verbose:
        print(f"python {platform.python_version()} ({sys.executable})")
        print(f"numpy {np.__version__}")
        print(f"extension {stripecal._core.__file__}")
    return 0


def _add_info(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("info", help="print the version", description=cmd_info.__doc__)
    p.add_argument("-v", "--verbose", action="store_true", help="also print versions and paths")
    p.set_defaults(func=cmd_info)


def _set_path(d: Dict[str, object], dotted: str, value: object) -> None:
    keys = dotted.split(".")
    for k in keys[:-1]:
        g = d.setdefault(k, {})
        if not isinstance(g, dict):
            raise stripecal.InvalidInputError(f"--set {dotted}: {k} is not a group of knobs")
        d = g
    d[keys[-1]] = value


def _overrides(args: argparse.Namespace) -> SimConfig:
    """The configuration overrides named by the simulate/demo options (knobs named on
    the command line: the twin checks them, naming the knob)."""
    over: Dict[str, object] = {}
    if getattr(args, "config", None):
        with open(args.config, encoding="utf-8") as f:
            try:
                loaded = json.load(f)
            except json.JSONDecodeError as e:
                raise stripecal.FormatError(f"{args.config}: line {e.lineno}: {e.msg}") from None
        if not isinstance(loaded, dict):
            raise stripecal.FormatError(f"{args.config}: expected a JSON object of knobs")
        over.update(loaded)
    simple = [
        ("seed", "seed"),
        ("poses", "poses.count"),
        ("noise", "imaging.noise_gray"),
        ("psf", "imaging.psf_sigma_px"),
        ("bit_depth", "imaging.bit_depth"),
        ("scan_step", "scan.step_mm"),
        ("scan_frames", "scan.max_frames"),
    ]
    for attr, path in simple:
        v = getattr(args, attr, None)
        if v is not None:
            _set_path(over, path, v)
    if getattr(args, "single_image", False):
        _set_path(over, "imaging.single_image", True)
    if getattr(args, "no_scan", False):
        _set_path(over, "scan.enabled", False)
    if getattr(args, "distortion", None):
        try:
            k = [float(x) for x in args.distortion.split(",")]
        except ValueError:
            raise stripecal.InvalidInputError(f"--distortion {args.distortion!r}: expected 5 numbers k1,k2,p1,p2,k3") from None
        if len(k) != 5:
            raise stripecal.InvalidInputError(f"--distortion: expected 5 numbers k1,k2,p1,p2,k3, got {len(k)}")
        _set_path(over, "camera.distortion", k)
    for item in getattr(args, "set", None) or []:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise stripecal.InvalidInputError(f"--set {item!r}: expected KEY=VALUE, e.g. imaging.noise_gray=2")
        try:
            value = json.loads(text)
        except json.JSONDecodeError:
            value = text  # a bare string, e.g. camera.distortion_model=opencv5
        _set_path(over, key, value)
    return cast(SimConfig, over)


def _add_knobs(p: argparse.ArgumentParser) -> None:
    p.add_argument("--preset", default="hp3-paper", choices=stripecal.sim.presets(), help="starting configuration (default hp3-paper)")
    p.add_argument("--seed", type=int, help="random seed: poses and noise (default 0)")
    p.add_argument("--poses", type=int, metavar="N", help="number of calibration views")
    p.add_argument("--noise", type=float, metavar="GRAY", help="read noise sigma in 8-bit gray levels")
    p.add_argument("--psf", type=float, metavar="PX", help="Gaussian PSF sigma in pixels")
    p.add_argument("--bit-depth", type=int, choices=[8, 16], help="image bit depth")
    p.add_argument("--single-image", action="store_true", help="one image per view holding circles and stripe")
    p.add_argument("--distortion", metavar="K1,K2,P1,P2,K3", help="true distortion coefficients")
    p.add_argument("--no-scan", action="store_true", help="render the calibration dataset only")
    p.add_argument("--scan-step", type=float, metavar="MM", help="sensor travel between scan frames")
    p.add_argument("--scan-frames", type=int, metavar="N", help="cap on the number of scan frames")
    p.add_argument("--config", metavar="FILE.json", help="a JSON object of knobs merged over the preset")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="any knob by its dotted path, value as JSON (repeatable), e.g. --set imaging.vignetting=0.3")
    p.add_argument("--print-config", action="store_true", help="print the full configuration and exit")


def _render(args: argparse.Namespace, out: str) -> Tuple[stripecal.sim.Twin, TwinSummary]:
    cfg = stripecal.sim.preset(args.preset, _overrides(args))
    twin = stripecal.sim.Twin(cfg)
    summary = twin.write(out, Progress())
    return twin, summary


def _print_profiler_summary(twin: stripecal.sim.Twin, summary: TwinSummary, elapsed: float) -> None:
    """The summary of the profiler mode (a profile dataset, no images)."""
    cfg = twin.config
    pc = cfg["profiler"]
    prof = summary["profiler"]
    assert prof is not None
    print(f"preset {cfg['preset']}, seed {cfg['seed']}: line profiler ({pc['line_length_mm']} mm line, "
          f"{pc['spacing_mm']} mm spacing), sphere {pc['sphere_diameter_mm']} mm, "
          f"robot {twin.robot_nominal.name}; rendered in {elapsed:.1f} s")
    views = summary["views"]
    print(f"\ncalibration views: {len(views)} profiles")
    dof = len(views[0]["q_deg"]) if views else 0
    header = "  view  " + " ".join(f"{'q' + str(i + 1):>8}" for i in range(dof))
    print(header + "   centre in sensor (x, y, z) mm    tilt   sphere  table  gaps  spikes")
    for i, (v, c) in enumerate(zip(views, prof["views"])):
        q = " ".join(f"{x:8.2f}" for x in v["q_deg"])
        x, y, z = c["sphere_center_sensor_mm"]
        print(f"  {i:>4}  {q}   ({x:6.1f}, {y:6.1f}, {z:6.1f})  {v['tilt_deg']:4.1f} deg"
              f"  {c['sphere']:>6} {c['table'] + c['stand']:>6} {c['gaps']:>5} {c['spikes']:>6}")
    print("  (joint readings in degrees; tilt of the sensor's z from its home direction)")
    print(f"\nwrote {summary['calib_dir']}  (rig.json, views.csv, profiles/, truth.json)")
    if summary["scan_dir"] is not None:
        print(f"wrote {summary['scan_dir']}  (rig.json, scan.csv, profiles/, truth.json; "
              f"{summary['scan_frames']} profiles, {summary['scan_sphere_points']} points on the sphere)")


def _print_summary(twin: stripecal.sim.Twin, summary: TwinSummary, elapsed: float) -> None:
    if summary.get("profiler") is not None:
        _print_profiler_summary(twin, summary, elapsed)
        return
    cfg = twin.config
    cam = twin.camera
    print(f"preset {cfg['preset']}, seed {cfg['seed']}: camera {cam.width} x {cam.height}, "
          f"board {cfg['board']['rows']} x {cfg['board']['cols']} (pitch {cfg['board']['pitch_mm']} mm), "
          f"robot {twin.robot_nominal.name}; rendered in {elapsed:.1f} s")
    views = summary["views"]
    total = summary["circles_total"]
    print(f"\ncalibration views: {len(views)} (board image + laser image each"
          f"{'; single-image mode: one image holds both' if cfg['imaging']['single_image'] else ''})")
    dof = len(views[0]["q_deg"]) if views else 0
    header = "  view  " + " ".join(f"{'q' + str(i + 1):>8}" for i in range(dof))
    print(header + "   stand-off   tilt   circles   stripe on board")
    # one stripe point per row when the stripe runs along columns, and vice versa
    lines = "rows" if summary["stripe_direction"] == "cols" else "columns"
    for i, v in enumerate(views):
        q = " ".join(f"{x:8.2f}" for x in v["q_deg"])
        print(f"  {i:>4}  {q}   {v['standoff_mm']:6.1f} mm  {v['tilt_deg']:4.1f} deg"
              f"  {v['circles_visible']:>3}/{total:<3}  {v['stripe_points_on_board']:>4} {lines}")
    bench = cfg.get("bench", {})
    if bench.get("enabled"):
        print("  (bench mode: a fixed sensor, no robot; stand-off = depth of the grid's centre;"
              " tilt between optical axis and board normal)")
    else:
        print("  (joint readings in degrees; stand-off along the optical axis to the board plane;"
              " tilt between optical axis and board normal)")
    sp = summary["sphere"]
    if bench.get("enabled") and summary["scan_dir"] is not None:
        print(f"\nconveyor scan (fixed sensor): {summary['scan_frames']} stripe images, the ball "
              f"({bench['scan']['sphere_diameter_mm']} mm) moved in {bench['scan']['step_mm']} mm steps; "
              f"{summary['scan_sphere_points']} stripe points on the ball in all (camera frame)")
    elif summary["scan_dir"] is not None and sp is not None:
        c = sp["center_mm"]
        print(f"\nball scan: {summary['scan_frames']} stripe images, sensor moving in a straight line in "
              f"{cfg['scan']['step_mm']} mm steps; ball diameter {sp['diameter_mm']} mm at "
              f"({c[0]:.2f}, {c[1]:.2f}, {c[2]:.2f}) mm in the base frame; "
              f"{summary['scan_sphere_points']} stripe points on the ball in all")
    print(f"\nwrote {summary['calib_dir']}  (rig.json, views.csv, images/, truth.json)")
    if summary["scan_dir"] is not None:
        print(f"wrote {summary['scan_dir']}  (rig.json, scan.csv, images/, truth.json)")
    if summary["table_dir"] is not None:
        print(f"wrote {summary['table_dir']}  (rig.json, scan.csv, images/, truth.json)")
    if summary["verify_dir"] is not None:
        print(f"wrote {summary['verify_dir']}  (artefacts.json, verify.csv, one scan folder per "
              f"artefact position; {summary['verify_frames']} stripe images)")


def cmd_simulate(args: argparse.Namespace) -> int:
    """Renders a calibration dataset (OUT/calib) and a ball scan (OUT/scan) of the digital
    twin, exactly in the files of spec/DATASET.md, with the ground truth in truth.json."""
    if args.print_config:
        print(json.dumps(stripecal.sim.preset(args.preset, _overrides(args)), indent=2))
        return 0
    t0 = time.monotonic()
    twin, summary = _render(args, args.out)
    _print_summary(twin, summary, time.monotonic() - t0)
    return 0


def _add_simulate(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("simulate", help="render a twin dataset with known truth", description=cmd_simulate.__doc__)
    p.add_argument("out", metavar="OUT", help="output folder (OUT/calib, OUT/scan are replaced)")
    _add_knobs(p)
    p.set_defaults(func=cmd_simulate)


# The paper's Table 2 (ERRATA.md readings): laser plane d with the sign that puts it in
# front of the camera; Z is not comparable (the paper's board frame is not recoverable).
PAPER_TABLE2: Dict[str, float] = {
    "fu (px)": 1271.65, "fv (px)": 1322.52, "u0 (px)": 346.14, "v0 (px)": 262.60, "k1": 0.0002,
    "laser normal x": 0.6290, "laser normal y": -0.0492, "laser normal z": 0.7759, "laser d (mm)": 79.8728,
    "X rotvec x (rad)": -0.3087, "X rotvec y (rad)": 0.2362, "X rotvec z (rad)": 3.0369,
    "X tx (mm)": 29.19, "X ty (mm)": 5.37, "X tz (mm)": 62.64,
}
PAPER_BALL_MM = [44.9414, 44.9227, 44.7862, 44.9367, 44.3355, 44.9528, 44.9378]
CMM_BALL_MM = 44.8614


def _param_rows(cal: stripecal.Calibration, truth: stripecal.Truth) -> List[Tuple[str, float, Optional[float], float]]:
    """(name, estimate, one-sigma, truth) of every estimated number."""
    from stripecal.report import parameter_rows

    return [(n, v, None if s is None else float(s), float(t) if t is not None else float("nan"))
            for n, v, s, t in parameter_rows(cal, truth)]


def _demo_tables(cal: stripecal.Calibration, truth: stripecal.Truth, m: SphereMeasurement, cloud_points: int) -> str:
    lines = [f"{'parameter':<20} {'true':>13} {'estimate':>13} {'1 sigma':>9} {'error':>10} {'paper Table 2':>14}"]
    for name, v, s, t in _param_rows(cal, truth):
        p = PAPER_TABLE2.get(name)
        sig = "" if s is None else f"{s:.2g}"
        pap = "" if p is None else f"{p:.4f}"
        lines.append(f"{name:<20} {t:13.6f} {v:13.6f} {sig:>9} {v - t:+10.2g} {pap:>14}")
    q = cal.quality
    lines.append("")
    lines.append(f"residual RMS: target points {q['target_rms_px']:.4f} px, stripe {q['stripe_rms_px']:.4f} px "
                 f"(paper: stripe re-projection 0.1364 +- 0.0849 px)")
    lines.append("")
    lines += sphere_lines(m, f"reference ball ({cloud_points} points), GUM budget (mm; U expanded, k = 2; "
                             f"the parts are standard uncertainties):")
    sphere = truth.sphere
    u = m["uncertainty"]
    if sphere is not None:
        td = float(sphere["diameter_mm"])
        tc = np.asarray(sphere["center_mm"], np.float64)
        lines.append("  against the truth:")
        for name, err, b in [("diameter", m["diameter_mm"] - td, u["diameter"])] + [
                (f"centre {a}", m["center_mm"][k] - tc[k], u["center"][k]) for k, a in enumerate("xyz")]:
            inside = "inside U" if abs(err) <= b["expanded_mm"] else "OUTSIDE U"
            lines.append(f"    {name:<10} error {err:+.5f} mm   U {b['expanded_mm']:.5f} mm   {inside}")
    d = m["diameter_mm"]
    lines.append(f"  against the CMM value {CMM_BALL_MM} mm: ours {d - CMM_BALL_MM:+.4f} +- "
                 f"{u['diameter']['expanded_mm']:.4f} mm (k = 2); the paper's seven measurements "
                 f"{', '.join(f'{x - CMM_BALL_MM:+.3f}' for x in PAPER_BALL_MM)} mm")
    return "\n".join(lines)


def cmd_demo(args: argparse.Namespace) -> int:
    """Renders the paper's rig (the hp3-paper twin: 5 calibration poses and a ball scan),
    calibrates it (one-stage), reconstructs the ball scan, fits the sphere, and prints
    truth, estimate +- 1 sigma and the paper's Table 2 side by side, then the ball's
    diameter against the CMM value and the paper's measurements. Writes the datasets,
    calibration.json, cloud.ply, sphere.json and an HTML report into the output folder."""
    t0 = time.monotonic()
    out = os.path.abspath(args.out)
    print(f"stripecal demo: rendering the {args.preset} digital twin into {out}")
    twin, summary = _render(args, args.out)
    _print_summary(twin, summary, time.monotonic() - t0)
    calib_dir = summary["calib_dir"]
    truth = stripecal.load_truth(os.path.join(calib_dir, "truth.json"))
    t1 = time.monotonic()
    cal = stripecal.calibrate(calib_dir)
    if not isinstance(cal, stripecal.Calibration):
        raise stripecal.InvalidInputError(f"the demo calibrates a camera's twin; {args.preset} renders a line profiler's "
                                          f"dataset: run stripecal calibrate {calib_dir}")
    cal.save(os.path.join(out, "calibration.json"))
    print(f"\ncalibrated {cal.quality['views_used']} views in {time.monotonic() - t1:.1f} s (one-stage adjustment)")
    if summary["scan_dir"] is None:
        print(_demo_tables_no_scan(cal, truth))
        return 0
    bar = Progress()
    cloud = stripecal.reconstruct_scan(cal, summary["scan_dir"], progress=lambda d, t, p: bar("reconstructing", d, t))
    cloud.save(os.path.join(out, "cloud.ply"))
    sphere_truth = stripecal.load_truth(os.path.join(summary["scan_dir"], "truth.json")).sphere
    d0 = float(sphere_truth["diameter_mm"]) if sphere_truth else CMM_BALL_MM
    m = stripecal.measure_sphere(cal, summary["scan_dir"], cloud=cloud, diameter_range_mm=(0.8 * d0, 1.2 * d0))
    write_json_atomic(os.path.join(out, "sphere.json"), m)
    scan_truth = stripecal.load_truth(os.path.join(summary["scan_dir"], "truth.json"))
    tables = _demo_tables(cal, scan_truth, m, len(cloud))
    print()
    print(tables)
    report = None
    try:
        from stripecal.report import write_report

        dist = np.linalg.norm(cloud.points - np.asarray(m["center_mm"]), axis=1) - 0.5 * m["diameter_mm"]
        report = write_report(os.path.join(out, "report"), cal, truth=truth, points=cloud.points,
                              point_colour=np.clip(dist, -0.2, 0.2), sections=[("Demo results", tables)],
                              title="stripecal demo: the hp3-paper twin")
    except ImportError as e:
        print(f"\nno report: {e}")
    print(f"\nwrote {out}: calib/, scan/, calibration.json, cloud.ply, sphere.json"
          f"{', report/index.html' if report else ''}  ({time.monotonic() - t0:.1f} s in all)")
    return 0


def _demo_tables_no_scan(cal: stripecal.Calibration, truth: stripecal.Truth) -> str:
    lines = [f"{'parameter':<20} {'true':>13} {'estimate':>13} {'1 sigma':>9}"]
    for name, v, s, t in _param_rows(cal, truth):
        lines.append(f"{name:<20} {t:13.6f} {v:13.6f} {'' if s is None else f'{s:.2g}':>9}")
    return "\n".join(lines)


def _add_demo(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("demo", help="render the paper's rig, calibrate it, measure the ball, write a report", description=cmd_demo.__doc__)
    p.add_argument("--out", default="stripecal-demo", help="output folder (default ./stripecal-demo)")
    _add_knobs(p)
    p.set_defaults(func=cmd_demo)


def _fmt_sigma(value: float, sigma: Optional[float]) -> str:
    if sigma is None:
        return f"{value:14.6f}"
    return f"{value:14.6f} +- {float(sigma):.2g}"


def print_calibration(cal: stripecal.Calibration) -> None:
    """Prints a calibration's parameters with their one-sigma, residuals and views."""
    from stripecal.report import parameter_rows, stripe_extraction_cells  # plain Python; matplotlib only for figures

    cam = cal.camera
    summary = cal.summary
    print(f"method {summary['method'] if summary else '?'}, camera model {cam.distortion_model}, "
          f"{cal.quality['views_used']} views used")
    print("\n  parameter                    value +- 1 sigma")
    for name, value, sigma, _ in parameter_rows(cal, None):
        print(f"  {name:<22}{_fmt_sigma(value, sigma or None)}")
    q = cal.quality
    smm = summary["stripe_rms_mm"] if summary else None
    stripe = (f", stripe {q['stripe_rms_px']:.4f} px ({smm:.4f} mm)" if cal.laser_plane is not None and smm is not None
              else " (no stripe points)")
    print(f"\n  residual RMS: target points {q['target_rms_px']:.4f} px{stripe}")
    channel = cal.stripe_channel
    if channel is not None:
        scores = cal.stripe_channel_scores
        how = ("auto: " + ", ".join(f"{k} {v:.0f}" for k, v in scores.items()) if scores is not None else "rig.json")
        print(f"  stripe found in the {channel} channel ({how})")
    views = cal.views
    if views:
        print("\n  view  used  target points  stripe found  left out  off plane  stripe pts  sat %"
              "  target RMS px  stripe RMS px  note")
        for v in views:
            crms = v["circle_rms_px"]
            srms = v["stripe_rms_px"]
            off = v["stripe_off_plane"]
            found, left, sat = stripe_extraction_cells(v)
            note = v["note"] or ("OUTLIER" if v["outlier"] else "")
            print(f"  {v['view']:>4}  {'yes' if v['used'] else 'no':>4}  {v['circles']:>13}  {found:>12}  {left:>8}"
                  f"  {'' if off is None else off:>9}  {v['stripe_points']:>10}  {sat:>5}"
                  f"  {'' if crms is None else f'{crms:.4f}':>13}  {'' if srms is None else f'{srms:.4f}':>13}  {note}")
    if cal.laser_plane is None:
        lasers = [v for v in views if v.get("stripe_extraction") is not None]
        why = ("no laser images" if not lasers else
               f"no laser line on the board in any of the {len(lasers)} laser images: see the warnings")
        print(f"\n  laser plane: not estimated ({why})")
    bs = cal.board_scale
    if bs is not None:
        what = "estimated" if bs["estimated"] else "implied by the robot"
        flag = "  DISAGREES with rig.json" if bs["disagrees"] else ""
        print(f"\n  board scale {what}: {bs['scale']:.5f} +- {bs['sigma']:.5f}"
              f" (rig.json {bs['declared_mm']:.3f} mm -> {bs['implied_mm']:.3f} mm){flag}")
    rn = cal.robot_pose_noise
    if rn is not None and rn["translation_mm"] is not None and rn["rotation_deg"] is not None:
        floor = [k for k, v in rn["at_floor"].items() if v]
        k = rn["image_factor"]
        image = f"; the images' own part {k:.3g} x their pose precision" if k is not None else ""
        print(f"\n  robot-pose noise: {rn['translation_mm']:.3g} mm, {rn['rotation_deg']:.3g} deg{image}"
              f" ({'at floor: ' + ', '.join(floor) if floor else 'estimated'})")
        km, kd = rn["kinematic_mm"], rn["kinematic_deg"]
        if km is not None and kd is not None:
            print(f"    DH errors of {km:.3g} mm / {kd:.3g} deg would explain it: their effect on X and Z is in the sigmas"
                  " (--robot auto estimates them)")
        tests = ", ".join(f"{v['view']}: {v['test']:.1f}" for v in rn["views"] if v["test"] is not None)
        if tests:
            print(f"    per-view pose test (above 4: the pose is off by far more than the others'): {tests}")
        for lv in rn["left_out"]:
            t = "?" if lv["test"] is None else f"{lv['test']:.1f}"
            tm, rd = lv["translation_mm"], lv["rotation_deg"]
            print(f"    view {lv['view']} LEFT OUT: its pose test {t} (corrected by "
                  f"{'?' if tm is None else f'{tm:.3f}'} mm, {'?' if rd is None else f'{rd:.4f}'} deg)")
    rc = cal.robot_calibration
    if rc is not None:
        print(f"\n  robot calibration ({rc['mode']}): {len(rc['estimated'])} DH corrections estimated,"
              f" {len(rc['fixed'])} held")
        for e in rc["estimated"]:
            c, s = e["correction"], e["sigma"]
            if c is not None and s is not None:
                print(f"    {e['name']:30s} {c:+.4f} +- {s:.4f}")
        for f in rc["fixed"]:
            print(f"    held {f['name']}: {f['reason']}")
    print_leave_one_out(cal)
    print_checks(q["checks"], q["accepted_poor"])
    for w in cal.warnings:
        print(f"  warning: {w}")


def print_checks(checks: Sequence[QualityCheck], accepted_poor: bool) -> None:
    """Prints the quality gates' verdicts."""
    if not checks:
        return
    print("\n  quality checks")
    for c in checks:
        mark = "ok" if c["passed"] else "FAILED"
        print(f"  {c['name']:<11} {mark:<6} {c['message']}")
    if accepted_poor:
        print("\n  ACCEPTED POOR: this calibration failed a quality check and was kept with"
              " --accept-poor; do not use it to accept or reject parts")


def print_leave_one_out(cal: stripecal.Calibration) -> None:
    """Prints the leave-one-view-out table: each view predicted by the calibration solved
    without it, from its robot pose (on the bench: from its own target points' board pose)."""
    loo = cal.leave_one_out
    if loo is None:
        return
    if cal.mount == "bench":
        print("\n  leave-one-view-out (each view's board pose from its own target points with the camera,"
              " and its stripe against that plane with the laser plane, of the calibration without it)")
    else:
        print("\n  leave-one-view-out (each view predicted from its robot pose by the calibration"
              " without it)")
    print("  view  points  board RMS px  board RMS mm  stripe RMS mm")
    for v in loo["views"]:
        s = v["stripe_rms_mm"]
        flag = "  DISAGREES" if v["disagrees"] else ""
        print(f"  {v['view']:>4}  {v['points']:>6}  {v['board_rms_px']:>12.4f}  {v['board_rms_mm']:>12.4f}"
              f"  {'' if s is None else f'{s:.4f}':>13}{flag}")
    ms = loo["median_stripe_rms_mm"]
    print(f"  median      {loo['median_board_rms_px']:>12.4f}  {loo['median_board_rms_mm']:>12.4f}"
          f"  {'' if ms is None else f'{ms:.4f}':>13}")
    lb = loo.get("laser_board")
    if lb is not None:
        print(f"  held-out laser->board distance (DECISIONS 8, {lb['points']} stripe points):"
              f" median {lb['median_mm']:.4f} mm, p95 {lb['p95_mm']:.4f} mm")


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Calibrates a dataset folder (rig.json, views.csv, images): camera, laser plane,
    hand-eye X and robot-world Z, with one-sigma uncertainties; a line profiler's dataset
    (rig.json sensor.kind "profiler", a profile column in views.csv): T_hand_sensor, the
    reference sphere and, with --robot, the robot (docs/profiler.md); writes calibration.json
    and prints the parameters, residuals and per-view figures. A calibration that fails a
    quality check (views whose robot pose does not fit their images and cannot be left
    out, undetermined parameters, no convergence) is printed for inspection and NOT
    written; the exit status is 1 (--accept-poor writes it, marked)."""
    t0 = time.monotonic()
    fix = [b.strip() for b in args.fix.split(",") if b.strip()] if args.fix else []
    if ([b for b in fix if b != "robot"] or args.laser_only) and not args.from_calibration:
        raise stripecal.InvalidInputError("--fix and --laser-only hold blocks of an earlier calibration: give it with --from FILE")
    try:
        cal = stripecal.calibrate(
            args.dataset, distortion=args.distortion, method=args.method, robust=args.robust,
            from_calibration=args.from_calibration, fix=fix, laser_only=args.laser_only,
            estimate_board_scale=args.estimate_board_scale, board_scale_tolerance=args.board_scale_tolerance,
            leave_one_out=not args.no_leave_one_out, accept_poor=args.accept_poor,
            robot_pose_noise=not args.no_robot_pose_noise,
            robot=args.robot, board_stripe_bias=not args.no_board_stripe_correction,
        )
    except stripecal.CalibrationQualityError as e:
        if isinstance(e.calibration, stripecal.Calibration):
            print("the calibration below FAILED its quality checks (shown for inspection):\n")
            print_calibration(e.calibration)
        else:
            print_checks(e.checks, False)
        failed = ", ".join(c["name"] for c in e.checks)
        print(f"\nstripecal calibrate: error: the calibration failed its quality checks ({failed}); "
              f"nothing written to {args.output}"
              + (" (--accept-poor writes it anyway, marked)" if e.calibration is not None else ""),
              file=sys.stderr)
        for c in e.checks:
            print(f"  {c['name']}: {c['message']}", file=sys.stderr)
        return 1
    elapsed = time.monotonic() - t0
    cal.save(args.output)
    if isinstance(cal, stripecal.ProfilerCalibration):
        print_profiler_calibration(cal)
    else:
        print_calibration(cal)
    print(f"\nwrote {os.path.abspath(args.output)}  ({elapsed:.1f} s)")
    if args.report:
        if isinstance(cal, stripecal.ProfilerCalibration):
            from stripecal.report_profiler import write_profiler_report

            page = write_profiler_report(args.report, cal)
        else:
            from stripecal.report import write_report

            page = write_report(args.report, cal)
        print(f"wrote {page}")
    return 0


def _add_calibrate(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("calibrate", help="calibrate a dataset folder", description=cmd_calibrate.__doc__)
    p.add_argument("dataset", metavar="DATASET", help="dataset folder (rig.json, views.csv, images)")
    p.add_argument("-o", "--output", default="calibration.json", help="output file (default calibration.json)")
    p.add_argument("--distortion", choices=["radial1", "radial2", "opencv5"], help="distortion model (default: the rig's)")
    p.add_argument("--method", choices=["one-stage", "paper"], default="one-stage",
                   help="one-stage (default): everything in one adjustment; paper: camera, plane, then AX = ZB")
    p.add_argument("--robust", action="store_true", help="Huber loss in the one-stage adjustment")
    p.add_argument("--from", dest="from_calibration", metavar="CALIBRATION.json",
                   help="start from an earlier calibration: the blocks named by --fix (or all but the laser plane with --laser-only) keep its values")
    p.add_argument("--fix", metavar="BLOCKS", help="blocks held at the --from values: camera,laser_plane,hand_cam,base_board (comma-separated)")
    p.add_argument("--laser-only", action="store_true", help="estimate the laser plane alone from laser views, everything else held from --from")
    p.add_argument("--estimate-board-scale", action="store_true",
                   help="free the board's printed scale (the robot's translations fix it); otherwise it is checked and a disagreement is warned about")
    p.add_argument("--board-scale-tolerance", type=float, default=0.01, metavar="REL",
                   help="the board-scale check warns when |scale - 1| exceeds 3 sigma and this (default 0.01)")
    p.add_argument("--no-leave-one-out", action="store_true", help="skip the leave-one-view-out figure (one refit per view)")
    p.add_argument("--robot", choices=["fixed", "offsets", "full", "auto"], default="fixed",
                   help="calibrate the robot's DH rows from the same images: offsets (encoder "
                        "offsets), full (every identifiable correction), auto (the corrections "
                        "the data show); default fixed (rig.json's DH table is exact; the same "
                        "as --fix robot). Needs joint readings")
    p.add_argument("--no-robot-pose-noise", action="store_true",
                   help="take the robot poses as exact (the paper's rigid model, for comparison); "
                        "default: every view's robot pose is corrected by its own small transform "
                        "and the robot-pose noise (mm, deg) is estimated and reported")
    p.add_argument("--robot-pose-noise", action="store_true",
                   help="accepted for older scripts, changes nothing: the robot-pose noise is the "
                        "default (--no-robot-pose-noise turns it off)")
    p.add_argument("--no-board-stripe-correction", action="store_true",
                   help="do not correct the laser stripe's sub-pixel bias on the board (default: "
                        "corrected before the final adjustment, what remains added to the "
                        "covariance; calibration.json's extra board_stripe_bias)")
    p.add_argument("--accept-poor", action="store_true",
                   help="write a calibration that failed a quality check anyway, marked quality.accepted_poor (default: exit 1, nothing written)")
    p.add_argument("--report", metavar="DIR", help="also write an HTML report with figures into DIR (needs matplotlib)")
    p.set_defaults(func=cmd_calibrate)


def cmd_detect(args: argparse.Namespace) -> int:
    """Detects the board of rig.json in every board image of a dataset folder (or in
    the images given with --rig) and prints, per image, the points found, the markers
    seen, the labellings the image leaves open (symmetric boards: the calibration
    decides them from the robot poses) and the residual of a homography through the
    points, or why the image is refused. With --csv, writes every point (view, row, col,
    u, v, flags) to a file. Exit status 1 when fewer than 3 images are detected."""
    if args.rig:
        rig = stripecal.load_rig(args.rig)
        images = list(args.inputs)
    else:
        if len(args.inputs) != 1:
            print("stripecal detect: give one DATASET folder, or --rig RIG and images", file=sys.stderr)
            return 2
        ds = stripecal.load_dataset(args.inputs[0])
        rig = ds.rig
        images = list(ds.board_images)  # already joined with the dataset folder
    board = rig.board
    print(f"board: {board.kind} {board.rows} x {board.cols}, {len(images)} images")
    print("\n  view  points  markers  alternatives  H rms px  image / reason")
    rows: List[str] = []
    found = 0
    for k, name in enumerate(images):
        # the size from the header: another size is refused before it is decoded
        image = stripecal.load_image(name, size=(rig.width, rig.height))
        try:
            det = stripecal.detect_target(image, board)
        except stripecal.DetectionError as e:
            print(f"  {k:>4}  {'-':>6}  {'-':>7}  {'-':>12}  {'-':>8}  {name}: {e}")
            continue
        found += 1
        markers = int(np.count_nonzero(det.flags & stripecal.TargetDetection.FLAG_MARKER))
        print(f"  {k:>4}  {len(det):>6}  {markers:>7}  {len(det.alternatives):>12}  "
              f"{det.homography_rms_px:>8.3f}  {name}")
        for (r, c), (u, v), f in zip(det.indices, det.points, det.flags):
            rows.append(f"{k},{int(r)},{int(c)},{float(u)!r},{float(v)!r},{int(f)}\n")
    print(f"\n{found} of {len(images)} images detected")
    if args.csv:
        _uninterruptible()
        folder = os.path.dirname(os.path.abspath(args.csv))
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{os.path.basename(args.csv)}.tmp-")
        try:
            with os.fdopen(fd, "w") as f:
                f.write("view,row,col,u,v,flags\n")
                f.writelines(rows)
            os.replace(tmp, args.csv)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
        print(f"wrote {os.path.abspath(args.csv)}")
    return 0 if found >= 3 else 1


def _add_detect(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("detect", help="detect the board in a dataset's images", description=cmd_detect.__doc__)
    p.add_argument("inputs", nargs="+", metavar="DATASET | IMAGE",
                   help="a dataset folder (rig.json, views.csv, images), or images with --rig")
    p.add_argument("--rig", metavar="RIG", help="rig.json whose board to detect in the IMAGE arguments")
    p.add_argument("--csv", metavar="FILE", help="write every detected point to FILE")
    p.set_defaults(func=cmd_detect)


def cmd_reconstruct(args: argparse.Namespace) -> int:
    """Reconstructs a scan folder (scan.csv + stripe images, spec/DATASET.md) with a
    calibration into a point cloud in the robot base frame (PLY: double x y z in mm plus
    per-point view, u, v, intensity, flags).

    A frame whose image cannot be used (missing or unreadable, truncated or corrupted,
    not the calibrated camera's size, another bit depth than most of the scan's frames)
    stops the run with an error naming the frame, its scan.csv line, the file and what
    is wrong (--on-bad-image stop, the default: exit status 1, nothing written). With
    --on-bad-image skip such frames are left out: they are listed here and in the PLY
    header (comment skipped_frames N, then one comment per frame). A frame that shows
    no stripe is not a bad image.

    The file is written only after every frame is done, atomically (a temporary file
    in the same folder renamed over it): it is complete, or absent and an earlier file
    at that path is left as it was. Ctrl-C (SIGINT) stops the run between chunks of
    frames, writes nothing and exits with status 130; once the file is being written,
    Ctrl-C is ignored and the command completes."""
    cal = load_any_calibration(args.calibration)
    bar = Progress()
    t0 = time.monotonic()
    seen = {"frames": 0}

    def progress(done: int, total: int, points: int) -> None:
        seen["frames"] = total
        dt = time.monotonic() - t0
        extra = f", {points / dt:,.0f} points/s" if dt > 0 and points else ""
        bar("reconstructing", done, total, extra)

    drop = stripecal.Stripe.BIASED if args.drop_biased else 0
    cloud = stripecal.reconstruct_scan(
        cal,
        args.scan_dir,
        direction=args.direction,
        min_ray_plane_angle_deg=args.min_angle_deg,
        drop_flags=drop,
        progress=progress,
        on_bad_image=args.on_bad_image,
        covariance=args.covariance,
    )
    dt = time.monotonic() - t0
    frames = seen["frames"]
    skipped = cloud.skipped_frames
    if len(cloud) == 0:
        why = f" ({len(skipped)} of {frames} frames skipped as bad images)" if skipped else ""
        raise stripecal.DetectionError(f"{args.scan_dir}: no stripe point in any frame{why}; nothing written")
    _uninterruptible()
    cloud.save(args.output, ascii=args.ascii)
    used = f"{frames - len(skipped)} of {frames} frames ({len(skipped)} skipped)" if skipped else f"{frames} frames"
    d = cloud.dropped
    print(f"{len(cloud)} points from {used} in {dt:.2f} s "
          f"({frames / dt:.1f} frames/s, {len(cloud) / dt:,.0f} points/s)")
    print(f"dropped: {d['grazing']} grazing rays, {d['undistort']} outside the distortion model, "
          f"{d['flagged']} flagged")
    if skipped:
        print(f"skipped {len(skipped)} frame{'s' if len(skipped) > 1 else ''} with a bad image (--on-bad-image skip):")
        shown = 20
        for b in skipped[:shown]:
            print(f"  frame {b['frame']} (scan.csv line {b['line']}): image {b['path']}: {b['reason']}")
        if len(skipped) > shown:
            print(f"  ... and {len(skipped) - shown} more (every one is listed in the PLY header)")
    where = "camera frame (a scan without poses)" if cloud.coordinate_frame == "cam" else "base frame"
    print(f"wrote {args.output} ({'ascii' if args.ascii else 'binary'} PLY, {where}, mm"
          f"{', per-point covariance' if args.covariance else ''}"
          f"{'; the header lists the skipped frames' if skipped else ''})")
    return 0


def _add_reconstruct(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("reconstruct", help="scan images + calibration -> point cloud (PLY)", description=inspect.cleandoc(cmd_reconstruct.__doc__ or ""),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("calibration", metavar="CALIBRATION.json", help="calibration result (spec: calibration.json)")
    p.add_argument("scan_dir", metavar="SCAN_DIR", help="scan folder: scan.csv and the images it names")
    p.add_argument("-o", "--output", required=True, metavar="CLOUD.ply", help="output point cloud")
    p.add_argument("--ascii", action="store_true", help="write ASCII PLY (default binary little-endian)")
    p.add_argument("--direction", default="auto", choices=["auto", "rows", "cols"],
                   help="stripe direction (default: the scan's rig.json hint, else from the laser plane)")
    p.add_argument("--min-angle-deg", type=float, default=2.0, metavar="DEG",
                   help="drop rays meeting the laser plane at less than this angle (default 2)")
    p.add_argument("--drop-biased", action="store_true",
                   help="drop stripe points flagged as biased (uneven background, oblique crossing)")
    p.add_argument("--on-bad-image", choices=["stop", "skip"], default="stop",
                   help="a frame whose image is missing, unreadable, truncated, corrupted, of the wrong size "
                        "or bit depth: stop with an error naming it and write nothing (default), or skip "
                        "it and list it in the output and the PLY header")
    p.add_argument("--covariance", action="store_true",
                   help="add each point's 3x3 covariance in the base frame (mm^2) as the PLY properties "
                        "cov_xx cov_xy cov_xz cov_yy cov_yz cov_zz: the calibration's covariance, the stripe's "
                        "noise (the calibration's stripe RMS) and the calibration robot's figures")
    p.set_defaults(func=cmd_reconstruct)


def cmd_fit_sphere(args: argparse.Namespace) -> int:
    """Fits a sphere (e.g. a reference ball) to a PLY point cloud: robust start (other
    surfaces such as the table are ignored), geometric least squares, outliers trimmed;
    prints diameter and centre with one-sigma, RMS, inliers and outliers. The one-sigma
    is the fit's random part (residual scatter); errors shared by all points, such as
    calibration errors, are not in it."""
    cloud = stripecal.read_ply(args.cloud)
    rng = diameter_range(args.diameter_range)
    fit = stripecal.fit_sphere(cloud["points"], trim_sigma=args.trim_sigma, diameter_range_mm=rng)
    sd = fit.fit_diameter_sigma_mm if fit.fit_diameter_sigma_mm is not None else float("nan")
    sc = fit.fit_center_sigma_mm if fit.fit_center_sigma_mm is not None else np.full(3, np.nan)
    c = fit.center_mm
    rows = [
        ("diameter", f"{fit.diameter_mm:.4f} mm", f"+- {sd:.2g} mm (1 sigma, random part)"),
        ("centre x", f"{c[0]:.4f} mm", f"+- {sc[0]:.2g} mm"),
        ("centre y", f"{c[1]:.4f} mm", f"+- {sc[1]:.2g} mm"),
        ("centre z", f"{c[2]:.4f} mm", f"+- {sc[2]:.2g} mm"),
        ("rms residual", f"{fit.rms_mm:.4f} mm", ""),
        ("points used", f"{fit.points}", ""),
        ("outliers", f"{fit.outliers}", f"(beyond {args.trim_sigma:g} robust sigmas)" if args.trim_sigma else ""),
    ]
    print(f"sphere fit of {args.cloud} ({len(cloud['points'])} points, base frame)")
    for name, value, note in rows:
        print(f"  {name:<13} {value:>16}  {note}".rstrip())
    print("  (the +- are the fit's random part only, as fit_*_sigma_mm in the file; the measurement's "
          "uncertainty, calibration and robot included: stripecal measure)")
    if args.output:
        fit.save(args.output)
        print(f"wrote {args.output}")
    return 0


def _add_fit_sphere(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("fit-sphere", help="fit a sphere to a point cloud (PLY)", description=cmd_fit_sphere.__doc__)
    p.add_argument("cloud", metavar="CLOUD.ply", help="point cloud (x y z in mm)")
    p.add_argument("-o", "--output", metavar="SPHERE.json", help="write the fit (spec: sphere fit JSON)")
    p.add_argument("--trim-sigma", type=float, default=3.0, metavar="K",
                   help="outlier threshold in robust sigmas (0: no trimming; default 3)")
    p.add_argument("--diameter-range", metavar="MIN,MAX",
                   help="accepted diameters of the robust start, mm (default: up to the cloud's size)")
    p.set_defaults(func=cmd_fit_sphere)


def _read_poses_csv(path: str) -> np.ndarray:
    """The joint vectors of a poses CSV: a header naming the columns, ``q1..qN`` among
    them (degrees; other columns ignored, so a views.csv works as it is), one pose a
    row. A row with another number of fields than the header, or a joint value that is
    not a number, is a FormatError naming the file and line."""
    import csv

    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise stripecal.FormatError(f"{path}: line 1: empty file, expected a header with q1..qN")
    header = [h.strip() for h in rows[0]]
    cols: List[int] = []
    while f"q{len(cols) + 1}" in header:
        cols.append(header.index(f"q{len(cols) + 1}"))
    if not cols:
        raise stripecal.FormatError(f"{path}: line 1: no joint columns q1..qN in the header")
    joints: List[List[float]] = []
    for n, row in enumerate(rows[1:], start=2):
        if not row or all(not x.strip() for x in row):
            continue
        if len(row) != len(header):
            raise stripecal.FormatError(
                f"{path}: line {n}: {len(row)} fields, the header has {len(header)}")
        try:
            joints.append([float(row[c]) for c in cols])
        except ValueError:
            raise stripecal.FormatError(f"{path}: line {n}: a joint value is not a number") from None
    if not joints:
        raise stripecal.FormatError(f"{path}: no pose rows after the header")
    return np.asarray(joints, dtype=np.float64)


_PLAN_GROUPS = [("camera", "camera"), ("laser_plane", "laser plane"), ("hand_cam", "hand_cam (X)"),
                ("base_board", "base_board (Z)"), ("board", "board")]


def cmd_plan(args: argparse.Namespace) -> int:
    """Checks a pose plan before driving the robot: from the robot joint vectors of
    POSES.csv (q1..qN, degrees; a views.csv works as it is), the rig (its robot and
    board) and a nominal calibration (calibration.json, or a twin's truth.json),
    predicts what each pose would see and the one-sigma every calibration parameter and
    a point measured at the stand-off would have with detections of the given noise.
    Prints a table per pose and the sigmas; --json writes the whole plan (atomically).
    Exit status 1 when fewer than 3 poses are usable or the poses leave a parameter
    undetermined (named)."""
    joints = _read_poses_csv(args.poses)
    pose_noise = None
    if args.pose_noise:
        try:
            mm, deg = (float(x) for x in args.pose_noise.split(","))
        except ValueError:
            raise stripecal.InvalidInputError(f"--pose-noise expects MM,DEG, got {args.pose_noise!r}") from None
        pose_noise = (mm, deg)
    plan = stripecal.plan_poses(args.rig, args.nominal, joints, sigma_px=(args.noise_px, args.stripe_noise_px),
                                standoff_mm=args.standoff, robot=args.robot, pose_noise=pose_noise)
    pn = plan["pose_noise_mm_deg"]
    noise = f"; robot-pose noise {pn[0]:.3g} mm, {pn[1]:.3g} deg" if pn is not None else ""
    print(f"{len(plan['poses'])} poses, {plan['usable']} usable; detection noise {plan['sigma_px'][0]:g} px "
          f"(targets), {plan['sigma_px'][1]:g} px (stripe){noise}\n")
    print("  pose  usable  points  stripe  stand-off mm  tilt deg  reason")
    for p in plan["poses"]:
        so, tilt = p["standoff_mm"], p["tilt_deg"]
        print(f"  {p['pose']:>4}  {'yes' if p['usable'] else 'NO':>6}  {p['points']:>6}  {p['stripe_points']:>6}  "
              f"{'-' if so is None else f'{so:.1f}':>12}  {'-' if tilt is None else f'{tilt:.1f}':>8}  {p['reason'] or ''}")
    print("\npredicted one-sigma of the parameters:")
    entries = plan["parameters"]
    for prefix, title in _PLAN_GROUPS:
        group = [e for e in entries if e["name"].split(".")[0] == prefix]
        if group:
            print(f"  {title}")
            for e in group:
                name = e["name"]
                unit = ("rad" if "rotation_vector" in name else "mm" if "_mm" in name
                        else "px" if prefix == "camera" and "distortion" not in name else "")
                print(f"    {e['name']:32} {e['sigma']:12.4g} {unit}")
    rest = [e for e in entries if e["name"].split(".")[0] not in {g for g, _ in _PLAN_GROUPS}]
    if rest:
        print("  other")
        for e in rest:
            print(f"    {e['name']:32} {e['sigma']:12.4g}")
    pt = plan["point"]
    if pt is not None:
        sc = pt["sigma_camera_mm"]
        print(f"\npoint on the laser plane at {pt['standoff_mm']:.1f} mm (pixel {pt['pixel'][0]:.1f}, {pt['pixel'][1]:.1f}):")
        print(f"  camera frame: sigma x {sc[0]:.4f}  y {sc[1]:.4f}  z {sc[2]:.4f}  |p| {pt['sigma_camera_norm_mm']:.4f} mm")
        sb, nb = pt["sigma_base_mm"], pt["sigma_base_norm_mm"]
        if sb is not None and nb is not None:
            print(f"  base frame (pose {pt['base_pose']}): sigma x {sb[0]:.4f}  y {sb[1]:.4f}  z {sb[2]:.4f}  |p| {nb:.4f} mm")
        sz, nz = pt["sigma_board_mm"], pt["sigma_board_norm_mm"]
        if sz is not None and nz is not None:
            print(f"  board frame (the world):  sigma x {sz[0]:.4f}  y {sz[1]:.4f}  z {sz[2]:.4f}  |p| {nz:.4f} mm")
    for h in plan["robot_held"]:
        print(f"  robot: held {h['name']}: {h['reason']}")
    for w in plan["warnings"]:
        print(f"warning: {w}")
    if args.output:
        _uninterruptible()
        write_json_atomic(args.output, plan)
        print(f"\nwrote {os.path.abspath(args.output)}")
    return 0


def _add_plan(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("plan", help="predict a pose plan's calibration uncertainty before driving the robot",
                       description=cmd_plan.__doc__)
    p.add_argument("--rig", required=True, metavar="RIG.json|DATASET", help="rig.json, or a dataset folder (its rig.json)")
    p.add_argument("--nominal", required=True, metavar="CALIBRATION.json",
                   help="the nominal calibration: calibration.json or a twin's truth.json")
    p.add_argument("--poses", required=True, metavar="POSES.csv",
                   help="joint vectors: a header with q1..qN (degrees), one pose a row; other columns ignored")
    p.add_argument("--noise-px", type=float, default=0.05, help="one-sigma of a target point's coordinates, px (default 0.05)")
    p.add_argument("--stripe-noise-px", type=float, default=0.1, help="one-sigma of a stripe point, px (default 0.1)")
    p.add_argument("--robot", choices=["fixed", "offsets", "full", "auto"], default="fixed",
                   help="plan a robot calibration too: the DH corrections' sigmas (auto is planned as full)")
    p.add_argument("--standoff", type=float, metavar="MM", help="stand-off of the predicted point, mm (default: the median pose's)")
    p.add_argument("--pose-noise", metavar="MM,DEG",
                   help="the robot-pose noise to plan with, one-sigma per flange component (default: the nominal "
                        "calibration's robot_pose_noise, else rig.json's robot figures, else an exact robot)")
    p.add_argument("--json", dest="output", metavar="OUT.json", help="write the plan as JSON (atomically)")
    p.set_defaults(func=cmd_plan)


_SUBCOMMANDS: List[Callable[[argparse._SubParsersAction[argparse.ArgumentParser]], None]] = [
    _add_info,
    _add_simulate,
    _add_demo,
    _add_detect,
    _add_calibrate,
    _add_reconstruct,
    _add_fit_sphere,
    add_measure,
    add_verify,
    _add_plan,
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="stripecal",
        description="Calibration and measurement for a robot-mounted laser-stripe sensor.",
    )
    parser.add_argument(
        "--version", action="version", version=f"%(prog)s {stripecal.__version__}"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in _SUBCOMMANDS:
        add(sub)
    return parser


# The SIGINT handler a command replaced with SIG_IGN at its point of no return
# (``_uninterruptible``); ``main`` puts it back.
_SAVED_SIGINT: List[Any] = []
# The SIGTERM handler ``main`` replaced with ``_on_sigterm`` (put back at its end).
_SAVED_SIGTERM: List[Any] = []
# A SIGTERM that arrived after the point of no return: the command completes its write,
# then ``main`` exits with 143.
_TERM_PENDING: List[bool] = []


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C's KeyboardInterrupt so that it takes the same way out:
    the library stops at its next check (or when it returns), nothing is half-written,
    no temporary file is left; ``main`` exits with 143 (128 + SIGTERM)."""


def _on_sigterm(signum: int, frame: Any) -> None:
    # Python runs this on the main thread between bytecodes: while the library works
    # (the GIL released) it runs at the library's next signal check or when it returns,
    # never in the middle of a file's write, so the atomic write completes or is never
    # begun.
    if _SAVED_SIGINT:  # past the point of no return: finish, then exit
        _TERM_PENDING.append(True)
        return
    raise _Terminated("terminated (SIGTERM)")


def _catch_sigterm() -> None:
    """SIGTERM (a service manager's stop, ``kill``) handled like Ctrl-C instead of ending
    the process where it stands, which left a hidden temporary file (or a simulator's
    staging folder) beside the target."""
    if threading.current_thread() is threading.main_thread() and not _SAVED_SIGTERM:
        _SAVED_SIGTERM.append(signal.signal(signal.SIGTERM, _on_sigterm))


def _uninterruptible() -> None:
    """The command's point of no return, just before it writes its output: from here to
    its end Ctrl-C is ignored and SIGTERM deferred, so the (atomic) write and the report
    of it complete. A Ctrl-C or SIGTERM that arrived before is raised here
    (``signal.signal`` runs pending handlers first): nothing has been written then."""
    if threading.current_thread() is threading.main_thread() and not _SAVED_SIGINT:
        _SAVED_SIGINT.append(signal.signal(signal.SIGINT, signal.SIG_IGN))


def _restore_sigint() -> None:
    while _SAVED_SIGINT:
        signal.signal(signal.SIGINT, _SAVED_SIGINT.pop())
    while _SAVED_SIGTERM:
        signal.signal(signal.SIGTERM, _SAVED_SIGTERM.pop())
    _TERM_PENDING.clear()


def _file_state(path: Optional[str]) -> Optional[Tuple[int, int, int]]:
    """(inode, mtime ns, size) of a file, None when there is none."""
    if not path:
        return None
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_ino, st.st_mtime_ns, st.st_size)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of the ``stripecal`` console script; returns the exit status: 0 done,
    1 an error (the message on stderr), 2 a usage error, 130 interrupted.

    Interrupts: Ctrl-C (SIGINT) makes a command stop, print ``interrupted; nothing
    written`` and return 130; SIGTERM does the same and returns 143 (once a command is
    writing its output, SIGTERM waits for the write to complete). Outputs are written atomically (a temporary file renamed
    over the target), so there is never a partial file or a temporary file left behind,
    and an earlier file at the output path is unchanged. ``reconstruct`` stops between
    chunks of frames and ignores Ctrl-C once it writes its file; ``calibrate`` stops when
    its current computation returns (the core cannot be interrupted mid-way) and, should
    the interrupt come after it wrote its file, says so. ``simulate`` and ``demo`` write
    their folders file by file: they say the folder may be incomplete."""
    command = "?"
    output: Optional[str] = None  # a file the command writes at its end, atomically
    folder: Optional[str] = None  # a folder it writes file by file (simulate, demo)
    before: Optional[Tuple[int, int, int]] = None
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        command = str(args.command)
        func: Optional[Callable[[argparse.Namespace], int]] = getattr(args, "func", None)
        if func is None:
            parser.print_help(sys.stderr)
            return 2
        out, fold = getattr(args, "output", None), getattr(args, "out", None)
        output = out if isinstance(out, str) else None
        folder = fold if isinstance(fold, str) else None
        before = _file_state(output)
        _catch_sigterm()
        try:
            status = func(args)
        except (stripecal.StripecalError, OSError) as e:
            print(f"stripecal {args.command}: error: {e}", file=sys.stderr)
            status = 1
        if _TERM_PENDING:
            print(f"stripecal {command}: terminated (SIGTERM) after completing its output", file=sys.stderr)
            return 143
        return status
    except KeyboardInterrupt as e:
        if getattr(sys.stderr, "isatty", lambda: False)():
            sys.stderr.write("\n")  # end a progress bar's line
        now = _file_state(output)
        if now is not None and now != before:
            what = f"{output} was already written"
        elif folder is not None:
            what = f"{folder} may be incomplete"
        else:
            what = "nothing written"
        term = isinstance(e, _Terminated)
        print(f"stripecal {command}: {'terminated (SIGTERM)' if term else 'interrupted'}; {what}", file=sys.stderr)
        return 143 if term else 130
    finally:
        _restore_sigint()


if __name__ == "__main__":
    raise SystemExit(main())
