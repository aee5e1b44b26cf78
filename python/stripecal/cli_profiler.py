"""The CLI's pages for a line profiler's calibration (issue 18): what ``stripecal
calibrate`` prints for a profile dataset. The numbers are the library's; this module only
formats them (calibration.json's keys, docs/profiler.md)."""

from __future__ import annotations

from typing import List, Optional, Sequence

import numpy as np

import stripecal
from stripecal.types import ProfilerMirrorTest, QualityCheck


def _f(x: Optional[float], spec: str) -> str:
    """A number formatted, ``nan`` for None (a non-finite number in the file)."""
    return format(float("nan") if x is None else x, spec)


def mirror_text(m: ProfilerMirrorTest) -> str:
    """The mirror test's sentence from calibration.json's ``mirror`` record."""
    d = m["delta_chi2"]
    return f"mirror test: the mirrored hand-eye fits worse by chi2 {'inf (no mirror minimum)' if d is None else f'{d:.4g}'}"


def parameter_rows(cal: stripecal.ProfilerCalibration) -> List[tuple[str, float, Optional[float]]]:
    """``(name, value, one-sigma)`` of the profiler's numbers: ``T_hand_sensor`` as
    rotation vector (rad) and translation (mm), the sphere's centre and diameter (mm)."""
    h = np.asarray(cal.hand_sensor)
    rv = stripecal.matrix_to_rotvec(h[:3, :3])
    u = cal.uncertainty
    hs = u.get("hand_cam", {})
    sp = u.get("sphere", {})
    rvs = list(hs.get("rotation_vector", [None] * 3))
    ts = list(hs.get("translation_mm", [None] * 3))
    cs = list(sp.get("center_mm", [None] * 3))
    rows: List[tuple[str, float, Optional[float]]] = []
    for k, a in enumerate("xyz"):
        rows.append((f"hand_sensor.r{a}", float(rv[k]), rvs[k]))
    for k, a in enumerate("xyz"):
        rows.append((f"hand_sensor.t{a}_mm", float(h[k, 3]), ts[k]))
    c = np.asarray(cal.sphere_center_mm)
    for k, a in enumerate("xyz"):
        rows.append((f"sphere.c{a}_mm", float(c[k]), cs[k]))
    rows.append(("sphere.diameter_mm", float(cal.sphere_diameter_mm), sp.get("diameter_mm")))
    return rows


def print_profiler_calibration(cal: stripecal.ProfilerCalibration) -> None:
    """Prints a profiler's calibration: parameters with one-sigma, residuals, views,
    the mirror test, the diameter check, the robot, leave-one-out, checks, warnings."""
    q = cal.quality
    est = "estimated" if cal.sphere_diameter_estimated else "declared"
    print(f"line profiler, {q['views_used']} profiles used, sphere diameter {est}")
    print("\n  parameter                    value +- 1 sigma")
    for name, value, sigma in parameter_rows(cal):
        s = "" if sigma is None else f" +- {float(sigma):.2g}"
        print(f"  {name:<22}{value:14.6f}{s}")
    adj = cal.adjustment
    k = adj["view_variance_factor"] if adj else None
    print(f"\n  profile RMS {q['profile_rms_mm']:.4f} mm over {adj['points_used'] if adj else '?'} sphere points"
          + (f" (view-clustered variance factor {k:.2f})" if k is not None else ""))
    views = cal.views
    if views:
        print("\n  view  used  points   gaps  sphere  rejected  RMS mm  side  note")
        for v in views:
            rms = v["rms_mm"]
            side = v["side"]
            print(f"  {v['view']!s:>4}  {'yes' if v['used'] else 'no':>4}  {v['points']!s:>6}  {v['gaps']!s:>5}"
                  f"  {v['sphere_points']!s:>6}  {v['rejected']!s:>8}  {'' if rms is None else f'{rms:.4f}':>6}"
                  f"  {'' if side is None else ('+' if side > 0 else '-'):>4}  {v['note'] or ''}")
    m = cal.mirror
    if m:
        sp = m["centre_spread_mm"]
        spread = ", ".join(f"{a} {x:.2f}" for a, x in (("x", sp["x"]), ("y", sp["y"]), ("z", sp["z"]),
                                                       ("across_plane", sp["across_plane"])) if x is not None)
        print(f"\n  {mirror_text(m)}; sphere centres in the sensor frame spread (mm): {spread}")
    dc = cal.diameter_check
    if dc:
        dflag = "  DISAGREES with rig.json" if dc["disagrees"] else ""
        print(f"  diameter check: declared {dc['declared_mm'] or 0:.4f} mm, the profiles say "
              f"{_f(dc['estimate_mm'], '.4f')} +- {_f(dc['sigma_mm'], '.4f')} mm{dflag}")
    rc = cal.robot_calibration
    if rc:
        print(f"\n  robot calibration ({rc['mode']}): {len(rc['estimated'])} DH corrections estimated, {len(rc['fixed'])} held")
        for x in rc["estimated"]:
            corr, sig = x["correction"], x["sigma"]
            if corr is not None and sig is not None:
                print(f"    {x['name']!s:30s} {corr:+.4f} +- {sig:.4f}")
    loo = cal.leave_one_out
    if loo:
        print(f"\n  leave-one-view-out: median held-out profile RMS {_f(loo['median_rms_mm'], '.4f')} mm"
              " (each profile against the sphere the other views predict from its robot pose)")
        for lv in loo["views"]:
            if lv["disagrees"]:
                print(f"    view {lv['view']} DISAGREES: {_f(lv['rms_mm'], '.4f')} mm")
    checks: Sequence[QualityCheck] = q.get("checks", [])
    if checks:
        print("\n  quality checks:")
        for chk in checks:
            print(f"    {chk['name']:<10} {'passed' if chk['passed'] else 'FAILED'}: {chk['message']}")
    if q.get("accepted_poor"):
        print("  ACCEPTED POOR: a quality check failed and the calibration was kept (--accept-poor)")
    for w in cal.warnings:
        print(f"  warning: {w}")
