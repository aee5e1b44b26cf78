"""The ``stripecal measure`` and ``stripecal verify`` subcommands: a scan's sphere, ball
bar or plane with GUM budgets, and the VDI/VDE 2634-2 style acceptance test. Parsing,
calling the library and printing only (the numbers come from the core)."""

from __future__ import annotations

import argparse
import inspect
import json
import os
import tempfile
from typing import Any, List, Optional, Tuple, Union

import stripecal
from stripecal._progress import Progress
from stripecal.types import Budget, SphereMeasurement, VerifyReport, VerifyRow, VerifySummary

_PARTS = "random", "calibration", "robot", "systematic"

TITLES = {"probing_form": "probing error form PF", "probing_size": "probing error size PS",
          "sphere_spacing": "sphere-spacing error SD", "flatness": "flatness measurement error F"}
"""The characteristics' names, in table order."""


def load_any_calibration(path: str) -> Union[stripecal.Calibration, stripecal.ProfilerCalibration]:
    """A calibration.json of either kind: a line profiler's (``"sensor": {"kind":
    "profiler"}``) or a camera's."""
    try:
        with open(path, encoding="utf-8") as f:
            sensor = json.load(f).get("sensor")
    except (OSError, ValueError, AttributeError):
        sensor = None  # the reader below says what is wrong
    if isinstance(sensor, dict) and sensor.get("kind") == "profiler":
        return stripecal.read_profiler_calibration(path)
    return stripecal.load_calibration(path)


def verdict(r: Union[VerifyRow, VerifySummary]) -> str:
    """``conforms`` (|value| + U <= MPE), ``pass`` (|value| <= MPE) or ``FAIL``."""
    return "conforms" if r["conforms"] else ("pass" if r["passed"] else "FAIL")


def budget_header() -> str:
    """The header line of a budget table (values and standard uncertainties in mm)."""
    return (f"  {'quantity':<16} {'value':>12} {'U (k=2)':>10} | {'random':>9} {'calibr.':>9} "
            f"{'robot':>9} {'system.':>9}")


def budget_line(name: str, b: Budget, unit: str = "mm") -> str:
    """One quantity: value, expanded uncertainty and the standard uncertainty per part."""
    parts = " ".join(f"{b[f'{p}_mm']:9.2e}" for p in _PARTS)  # type: ignore[literal-required]
    return f"  {name:<16} {b['value_mm']:12.5f} {b['expanded_mm']:10.2e} | {parts}  {unit}"


def sphere_lines(m: SphereMeasurement, title: str) -> List[str]:
    u = m["uncertainty"]
    lines = [title, budget_header(), budget_line("diameter", u["diameter"])]
    for k, axis in enumerate("xyz"):
        lines.append(budget_line(f"centre {axis}", u["center"][k]))
    lines.append(budget_line("probing form", u["form"]))
    bias = m["stripe_bias"]
    if bias is not None:
        lines.append(f"  stripe bias corrected: diameter {bias['diameter_change_mm']:+.5f} mm "
                     f"(sheet sigma {bias['sheet_sigma_mm']:.3f} mm from the stripe's width)")
        if bias["points_saturated"]:
            lines.append(f"  {bias['points_saturated']} saturated stripe points left out of the "
                         "corrected fit (the bias model has no clipping)")
    carried = m["calibration_emitter"]
    if carried is not None:
        x, sd = carried["offset_mm"], carried["sd_mm"]
        where = f"emitter {x[0]:+.1f} +- {sd[0]:.1f}, {x[1]:+.1f} +- {sd[1]:.1f} mm from the calibration's"
        if carried["applied"]:
            lines.append(f"  calibration moved to the {where} (its emitter range replaced)")
        else:
            lines.append(f"  calibration kept as it is ({where}): {carried['reason']}")
    lines.append(f"  {m['points']} points used, {m['outliers']} trimmed, RMS {m['rms_mm']:.5f} mm")
    return lines


def write_json_atomic(path: str, value: Any) -> None:
    """Writes JSON atomically (a temporary file in the target's folder, renamed)."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=".json")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(value, f, indent=2)
            f.write("\n")
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def diameter_range(text: Optional[str]) -> Optional[Tuple[float, float]]:
    """``--diameter-range MIN,MAX`` (mm) as a tuple; None when not given."""
    if not text:
        return None
    try:
        lo, hi = (float(x) for x in text.split(","))
    except ValueError:
        raise stripecal.InvalidInputError(f"--diameter-range {text!r}: expected MIN,MAX in mm") from None
    return (lo, hi)


def cmd_measure(args: argparse.Namespace) -> int:
    """Measures a scan's sphere (the reference ball), ball bar (two spheres and their
    centres' distance) or plane with GUM budgets: for every quantity its value, the
    expanded uncertainty U (k = 2: the headline) and the standard uncertainties of its
    parts: random (the fit's scatter), calibration (the calibration's covariance carried
    through every point: shared, it does not average out), robot (--repeatability-mm,
    --encoder-sigma-deg, or the calibration robot's figures) and systematic (what the
    curved-surface stripe-bias correction of a sphere leaves). Spheres are corrected for
    that bias unless --no-bias-correction. docs/measurement.md has the maths."""
    cal = load_any_calibration(args.calibration)
    bar = Progress()
    cloud = stripecal.reconstruct_scan(cal, args.scan_dir, progress=lambda d, t, p: bar("reconstructing", d, t))
    common: Any = dict(cloud=cloud, stripe_sigma_px=args.stripe_sigma_px, repeatability_mm=args.repeatability_mm,
                       encoder_sigma_deg=args.encoder_sigma_deg)
    lines: List[str]
    result: Any
    if args.shape == "plane":
        p = stripecal.measure_plane(cal, args.scan_dir, **common)
        u = p["uncertainty"]
        lines = [f"plane of {args.scan_dir} (base frame)", budget_header(),
                 budget_line("flatness", u["flatness"]), budget_line("offset d", u["offset"]),
                 budget_line("tilt 1", u["tilt_deg"][0], "deg"), budget_line("tilt 2", u["tilt_deg"][1], "deg"),
                 f"  {p['points']} points used, {p['outliers']} trimmed, RMS {p['rms_mm']:.5f} mm"]
        result = p
    else:
        kw: Any = dict(common, diameter_range_mm=diameter_range(args.diameter_range), correct_bias=not args.no_bias_correction)
        if args.shape == "sphere":
            s = stripecal.measure_sphere(cal, args.scan_dir, **kw)
            lines = sphere_lines(s, f"sphere of {args.scan_dir} (base frame)")
            result = s
        else:
            b = stripecal.measure_ball_bar(cal, args.scan_dir, **kw)
            lines = []
            for k, s in enumerate(b["spheres"]):
                lines += sphere_lines(s, f"sphere {k + 1} of the ball bar in {args.scan_dir}")
            lines += ["centre distance", budget_header(), budget_line("distance", b["distance"])]
            result = b
    print("\n".join(lines))
    if args.json:
        write_json_atomic(args.json, result)
        print(f"wrote {args.json}")
    return 0


def _add_uncertainty_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--stripe-sigma-px", type=float, metavar="PX",
                   help="one-sigma of the stripe centre (default: the calibration's quality.stripe_rms_px)")
    p.add_argument("--repeatability-mm", type=float, metavar="MM",
                   help="robot pose repeatability, read as a one-sigma per axis (default: the calibration robot's)")
    p.add_argument("--encoder-sigma-deg", type=float, metavar="DEG",
                   help="one-sigma of a joint reading (default: the calibration robot's)")
    p.add_argument("--no-bias-correction", action="store_true",
                   help="do not correct spheres for the curved-surface stripe bias")


def add_measure(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("measure", help="measure a scan's sphere, ball bar or plane with GUM budgets",
                       description=inspect.cleandoc(cmd_measure.__doc__ or ""),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("calibration", metavar="CALIBRATION.json", help="calibration result")
    p.add_argument("scan_dir", metavar="SCAN_DIR", help="scan folder: scan.csv and the images it names")
    p.add_argument("--shape", choices=["sphere", "ball-bar", "plane"], default="sphere", help="what the scan shows")
    p.add_argument("--diameter-range", metavar="MIN,MAX", help="accepted sphere diameters, mm")
    p.add_argument("--json", metavar="OUT.json", help="write the measurement with its budgets")
    _add_uncertainty_args(p)
    p.set_defaults(func=cmd_measure)


def verify_lines(r: VerifyReport) -> List[str]:
    """The acceptance test's table: every measured value, then the verdict per
    characteristic."""
    lines = [f"  {'':<2} {'scan':<12} {'artefact':<12} {'value mm':>10} {'U (k=2)':>9} {'MPE':>8}  verdict"]
    for row in r["rows"]:
        b = row["budget"]
        lines.append(f"  {row['symbol']:<2} {row['scan']:<12} {row['artefact']:<12} {b['value_mm']:+10.5f} "
                     f"{b['expanded_mm']:9.5f} {row['mpe_mm']:8.4f}  {verdict(row)}")
    lines.append("")
    lines.append(f"  {'characteristic':<34} {'worst mm':>10} {'U (k=2)':>9} {'MPE':>8}  n  verdict")
    for key, title in TITLES.items():
        s = r["summary"].get(key)
        if s is None:
            lines.append(f"  {title:<34} {'not measured':>10}")
            continue
        lines.append(f"  {title:<34} {s['worst_mm']:+10.5f} {s['expanded_mm']:9.5f} {s['mpe_mm']:8.4f} "
                     f"{s['measurements']:2d}  {verdict(s)}")
    lines.append("")
    lines.append("  pass: |value| <= MPE; conforms: |value| + U <= MPE (ISO 14253-1)")
    lines.append(f"  acceptance test {'PASSED' if r['passed'] else 'FAILED'}")
    return lines


def cmd_verify(args: argparse.Namespace) -> int:
    """The VDI/VDE 2634 Part 2 style acceptance test. FOLDER holds artefacts.json (the
    artefacts' certified values and the maximum permissible errors, spec/DATASET.md),
    verify.csv (header scan,artefact: one scan folder per line and the ball bar, plane or
    sphere of artefacts.json it shows) and the scans. Every scan is reconstructed and
    measured with its budget; the table lists the probing error form PF (range of a
    sphere's radial residuals), probing error size PS (diameter error), sphere-spacing
    error SD (ball-bar length error) and flatness measurement error F (range of a plate's
    residuals), each with its expanded uncertainty, against the MPE. Exit status 0 when
    every value is within its MPE, 3 when one is not (1: an error)."""
    cal = load_any_calibration(args.calibration)
    bar = Progress()
    r = stripecal.verify(cal, args.folder, artefacts=args.artefacts, correct_bias=not args.no_bias_correction,
                         stripe_sigma_px=args.stripe_sigma_px, repeatability_mm=args.repeatability_mm,
                         encoder_sigma_deg=args.encoder_sigma_deg,
                         progress=lambda stage, d, t: bar("measuring", d, t))
    print(f"acceptance test of {args.calibration} on {args.folder} (VDI/VDE 2634-2 style)")
    print("\n".join(verify_lines(r)))
    if args.json:
        write_json_atomic(args.json, r)
        print(f"wrote {args.json}")
    if args.report:
        from stripecal.report_verify import write_verify_report

        path = write_verify_report(args.report, r, title=f"Acceptance test: {args.folder}")
        print(f"wrote {path}")
    return 0 if r["passed"] else 3


def add_verify(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("verify", help="VDI/VDE 2634-2 style acceptance test on scans of certified artefacts",
                       description=inspect.cleandoc(cmd_verify.__doc__ or ""),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("calibration", metavar="CALIBRATION.json", help="calibration result")
    p.add_argument("folder", metavar="FOLDER", help="folder with artefacts.json, verify.csv and the scans")
    p.add_argument("--artefacts", metavar="ARTEFACTS.json", help="the artefacts file (default FOLDER/artefacts.json)")
    p.add_argument("--json", metavar="OUT.json", help="write the report (stripecal/verify@1)")
    p.add_argument("--report", metavar="DIR", help="write an HTML report of the test into DIR")
    _add_uncertainty_args(p)
    p.set_defaults(func=cmd_verify)
