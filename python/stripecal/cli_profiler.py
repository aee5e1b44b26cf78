"""The CLI's pages for a line profiler's calibration (issue 18): what ``stripecal
calibrate`` prints for a profile dataset. The numbers are the library's; this module only
formats them (calibration.json's keys, docs/profiler.md)."""

from __future__ import annotations

from typing import List, Mapping, Optional, Sequence

import numpy as np

import stripecal
from stripecal.types import QualityCheck


def _num(x: object) -> Optional[float]:
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) else None


def _list(x: object) -> List[object]:
    return list(x) if isinstance(x, list) else []


def _map(x: object) -> Mapping[str, object]:
    return x if isinstance(x, dict) else {}


def mirror_text(m: Mapping[str, object]) -> str:
    """The mirror test's sentence from calibration.json's ``mirror`` record."""
    d = _num(m.get("delta_chi2"))
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
    e = cal.extra
    est = "estimated" if e.get("sphere_diameter_estimated") else "declared"
    print(f"line profiler, {q['views_used']} profiles used, sphere diameter {est}")
    print("\n  parameter                    value +- 1 sigma")
    for name, value, sigma in parameter_rows(cal):
        s = "" if sigma is None else f" +- {float(sigma):.2g}"
        print(f"  {name:<22}{value:14.6f}{s}")
    adj = _map(e.get("adjustment"))
    k = _num(adj.get("view_variance_factor"))
    print(f"\n  profile RMS {q['profile_rms_mm']:.4f} mm over {adj.get('points_used', '?')} sphere points"
          + (f" (view-clustered variance factor {k:.2f})" if k is not None else ""))
    views = [_map(v) for v in _list(e.get("views"))]
    if views:
        print("\n  view  used  points   gaps  sphere  rejected  RMS mm  side  note")
        for v in views:
            rms = _num(v.get("rms_mm"))
            side = _num(v.get("side"))
            print(f"  {v.get('view')!s:>4}  {'yes' if v.get('used') else 'no':>4}  {v.get('points')!s:>6}  {v.get('gaps')!s:>5}"
                  f"  {v.get('sphere_points')!s:>6}  {v.get('rejected')!s:>8}  {'' if rms is None else f'{rms:.4f}':>6}"
                  f"  {'' if side is None else ('+' if side > 0 else '-'):>4}  {v.get('note') or ''}")
    m = _map(e.get("mirror"))
    if m:
        sp = _map(m.get("centre_spread_mm"))
        spread = ", ".join(f"{a} {_num(sp.get(a)):.2f}" for a in ("x", "y", "z", "across_plane") if _num(sp.get(a)) is not None)
        print(f"\n  {mirror_text(m)}; sphere centres in the sensor frame spread (mm): {spread}")
    dc = _map(e.get("diameter_check"))
    if dc:
        dflag = "  DISAGREES with rig.json" if dc.get("disagrees") else ""
        print(f"  diameter check: declared {_num(dc.get('declared_mm')) or 0:.4f} mm, the profiles say "
              f"{_num(dc.get('estimate_mm')) or float('nan'):.4f} +- {_num(dc.get('sigma_mm')) or float('nan'):.4f} mm{dflag}")
    rc = _map(e.get("robot_calibration"))
    if rc:
        est_l = [_map(x) for x in _list(rc.get("estimated"))]
        fixed = [_map(x) for x in _list(rc.get("fixed"))]
        print(f"\n  robot calibration ({rc.get('mode')}): {len(est_l)} DH corrections estimated, {len(fixed)} held")
        for x in est_l:
            corr, sig = _num(x.get("correction")), _num(x.get("sigma"))
            if corr is not None and sig is not None:
                print(f"    {x.get('name')!s:30s} {corr:+.4f} +- {sig:.4f}")
    loo = _map(e.get("leave_one_out"))
    if loo:
        print(f"\n  leave-one-view-out: median held-out profile RMS {_num(loo.get('median_rms_mm')) or float('nan'):.4f} mm"
              " (each profile against the sphere the other views predict from its robot pose)")
        for x in (_map(v) for v in _list(loo.get("views"))):
            if x.get("disagrees"):
                print(f"    view {x.get('view')} DISAGREES: {_num(x.get('rms_mm')) or float('nan'):.4f} mm")
    checks: Sequence[QualityCheck] = q.get("checks", [])
    if checks:
        print("\n  quality checks:")
        for chk in checks:
            print(f"    {chk['name']:<10} {'passed' if chk['passed'] else 'FAILED'}: {chk['message']}")
    if q.get("accepted_poor"):
        print("  ACCEPTED POOR: a quality check failed and the calibration was kept (--accept-poor)")
    for w in _list(e.get("warnings")):
        print(f"  warning: {w}")
