"""HTML report of a calibration (and optionally of a measured cloud), with PNG figures.

Needs matplotlib (``pip install 'stripecal[report]'``); the rest of stripecal does not.
The report draws what the library computed: it adds no numerics of its own beyond
picking columns and scaling arrows for display.

Figures (one PNG each, referenced by ``index.html``):

- ``circle_residuals.png``: per view, each circle's residual as an arrow at its image
  position (arrows scaled, the scale printed), the view's RMS in the title;
- ``stripe_residuals.png``: per view, the stripe points' signed distance from their
  predicted line along the scan direction;
- ``view_rms.png``: circle and stripe RMS per view (bad views stand out);
- ``residual_histogram.png``: histograms of the circle (u and v) and stripe residuals;
- ``cloud.png`` (with a cloud): two projections of the points, coloured by their
  distance from the fitted sphere when given.
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

import stripecal
from stripecal.types import CalibrationQuality, CalibrationView, CameraSigma, PlaneSigma, PoseSigma, ProfilerQuality

_Path = Union[str, "os.PathLike[str]"]
F64 = npt.NDArray[np.float64]


def _pyplot() -> Any:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as e:  # pragma: no cover - depends on the install
        raise ImportError(
            "the report needs matplotlib: pip install 'stripecal[report]'"
        ) from e
    return plt


def _grid(n: int) -> Tuple[int, int]:
    cols = min(n, 3)
    rows = (n + cols - 1) // cols
    return rows, cols


def _save(plt: Any, fig: Any, out: Path, name: str, tight: bool = True) -> str:
    """Lays out (unless `tight` is false), writes `out/name` atomically, closes the
    figure and returns `name`."""
    if tight:
        fig.tight_layout()
    path = out / name
    tmp = path.with_name(path.name + ".tmp")
    fig.savefig(tmp, format="png", dpi=90)
    os.replace(tmp, path)
    plt.close(fig)
    return name


def _circle_figure(plt: Any, cal: stripecal.Calibration, out: Path) -> Optional[str]:
    cr = cal.circle_residuals
    if cr.shape[0] == 0:
        return None
    views = sorted({int(v) for v in cr[:, 0]})
    rows, cols = _grid(len(views))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.4 * rows), squeeze=False)
    mag = np.hypot(cr[:, 5], cr[:, 6])
    peak = float(mag.max()) if mag.size and mag.max() > 0 else 1.0
    scale = 40.0 / peak  # the largest arrow is 40 px long on the image
    cam = cal.camera
    for ax, v in zip(axes.ravel(), views):
        m = cr[:, 0] == v
        rms = float(np.sqrt(np.mean(cr[m, 5] ** 2 + cr[m, 6] ** 2)))
        ax.quiver(cr[m, 3], cr[m, 4], cr[m, 5] * scale, cr[m, 6] * scale, angles="xy",
                  scale_units="xy", scale=1.0, width=0.004, color="tab:red")
        ax.plot(cr[m, 3], cr[m, 4], ".", ms=2, color="k")
        ax.set_xlim(0, cam.width)
        ax.set_ylim(cam.height, 0)
        ax.set_aspect("equal")
        ax.set_title(f"view {v}: RMS {rms:.4f} px", fontsize=9)
    for ax in axes.ravel()[len(views):]:
        ax.axis("off")
    fig.suptitle(f"target point residuals (predicted - detected), arrows x{scale:.0f}; largest {peak:.4f} px", fontsize=10)
    return _save(plt, fig, out, "circle_residuals.png")


def _stripe_figure(plt: Any, cal: stripecal.Calibration, out: Path) -> Optional[str]:
    sr = cal.stripe_residuals
    if sr.shape[0] == 0:
        return None
    fig, ax = plt.subplots(figsize=(8, 3.6))
    # position along the stripe: the coordinate that varies more
    along = 2 if np.ptp(sr[:, 2]) >= np.ptp(sr[:, 1]) else 1
    for v in sorted({int(x) for x in sr[:, 0]}):
        m = sr[:, 0] == v
        ax.plot(sr[m, along], sr[m, 3], ".", ms=2, label=f"view {v}")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel(("u" if along == 1 else "v") + " (px, along the stripe)")
    ax.set_ylabel("distance from predicted line (px)")
    ax.legend(fontsize=7, markerscale=4, ncol=4)
    ax.set_title("stripe residuals", fontsize=10)
    return _save(plt, fig, out, "stripe_residuals.png")


def _rms_figure(plt: Any, cal: stripecal.Calibration, out: Path) -> Optional[str]:
    views = [v for v in cal.views if v["used"]]
    if not views:
        return None
    fig, ax = plt.subplots(figsize=(max(4.0, 0.6 * len(views) + 2), 3.2))
    x = np.arange(len(views))
    c = [v["circle_rms_px"] or 0.0 for v in views]
    s = [v["stripe_rms_px"] or 0.0 for v in views]
    ax.bar(x - 0.2, c, 0.4, label="target points (2D RMS)")
    ax.bar(x + 0.2, s, 0.4, label="stripe (RMS distance)")
    for i, v in enumerate(views):
        if v["outlier"]:
            ax.annotate("outlier", (x[i], max(c[i], s[i])), ha="center", va="bottom", color="red", fontsize=8)
    ax.set_xticks(x)
    ax.set_xticklabels([str(v["view"]) for v in views])
    ax.set_xlabel("view")
    ax.set_ylabel("px")
    ax.legend(fontsize=8)
    ax.set_title("residual RMS per view", fontsize=10)
    return _save(plt, fig, out, "view_rms.png")


def _hist_figure(plt: Any, cal: stripecal.Calibration, out: Path) -> Optional[str]:
    cr, sr = cal.circle_residuals, cal.stripe_residuals
    if cr.shape[0] == 0 and sr.shape[0] == 0:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(8, 3.2))
    if cr.shape[0]:
        axes[0].hist([cr[:, 5], cr[:, 6]], bins=40, label=["du", "dv"], histtype="step")
        axes[0].legend(fontsize=8)
    axes[0].set_title("target point residuals (px)", fontsize=10)
    if sr.shape[0]:
        axes[1].hist(sr[:, 3], bins=60, histtype="step", color="tab:green")
    axes[1].set_title("stripe residuals (px)", fontsize=10)
    return _save(plt, fig, out, "residual_histogram.png")


def _cloud_figure(plt: Any, points: F64, colour: Optional[F64], out: Path) -> Optional[str]:
    if points.shape[0] == 0:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(9, 4))
    for ax, (i, j, name) in zip(axes, ((0, 1, "x-y"), (0, 2, "x-z"))):
        sc = ax.scatter(points[:, i], points[:, j], c=colour if colour is not None else points[:, 2],
                        s=1, cmap="coolwarm" if colour is not None else "viridis")
        ax.set_aspect("equal")
        ax.set_xlabel("xyz"[i] + " (mm)")
        ax.set_ylabel("xyz"[j] + " (mm)")
        ax.set_title(f"{name} projection, base frame", fontsize=10)
    fig.colorbar(sc, ax=axes, label="distance from sphere (mm)" if colour is not None else "z (mm)")
    return _save(plt, fig, out, "cloud.png", tight=False)


Row = Tuple[str, float, Optional[float], Optional[float]]
"""A parameter row: name, estimate, one-sigma (None when unknown), true value (None
without a truth)."""


def _at(values: Optional[Sequence[Optional[float]]], i: int) -> Optional[float]:
    """Element ``i`` of a list of one-sigmas; None when the list is missing or short."""
    if values is None or i >= len(values):
        return None
    return values[i]


def _no_plane_reason(cal: stripecal.Calibration) -> str:
    """Why a calibration has no laser plane: no laser images, or no line on the board."""
    lasers = [v for v in cal.views if v.get("stripe_extraction") is not None]
    if not lasers:
        return "no laser images"
    return f"no laser line on the board in any of the {len(lasers)} laser images, see the warnings"


def stripe_extraction_cells(v: CalibrationView) -> Tuple[str, str, str]:
    """A view's stripe extraction as the views table shows it (CLI and report): points
    found, points left out (at an edge, on an uneven background, oblique) and the
    saturated share in percent; empty cells for a view without a record."""
    ex = v.get("stripe_extraction")
    if ex is None:
        return "", "", ""
    lo = ex["left_out"]
    share = ex["saturated_share"]
    return (str(ex["found"]), str(lo["at_edge"] + lo["uneven_background"] + lo["oblique"]),
            "" if share is None else f"{100 * share:.0f}")


def parameter_rows(cal: stripecal.Calibration, truth: Optional[stripecal.Truth]) -> List[Row]:
    """(name, value, one-sigma or None, true value or None) per estimated number."""
    u = cal.uncertainty
    cam = cal.camera
    cu: CameraSigma = u.get("camera", {})
    intrinsics: List[Tuple[str, float, Optional[float], Optional[float]]] = [
        ("fu", cam.fu, cu.get("fu"), truth.camera.fu if truth else None),
        ("fv", cam.fv, cu.get("fv"), truth.camera.fv if truth else None),
        ("u0", cam.u0, cu.get("u0"), truth.camera.u0 if truth else None),
        ("v0", cam.v0, cu.get("v0"), truth.camera.v0 if truth else None),
    ]
    out: List[Row] = [(f"{n} (px)", v, s, t) for n, v, s, t in intrinsics]
    ds = cu.get("distortion")
    for i, n in enumerate(("k1", "k2", "p1", "p2", "k3")):
        if cam.distortion[i] != 0.0 or _at(ds, i):
            out.append((n, float(cam.distortion[i]), _at(ds, i), float(truth.camera.distortion[i]) if truth else None))
    plane = cal.laser_plane
    if plane is not None:  # None: not estimated (no laser images)
        n_, d_ = plane
        lu: PlaneSigma = u.get("laser_plane", {})
        tn: Optional[Tuple[F64, float]] = truth.laser_plane if truth else None
        for i, a in enumerate("xyz"):
            out.append((f"laser normal {a}", float(n_[i]), _at(lu.get("normal"), i), float(tn[0][i]) if tn else None))
        out.append(("laser d (mm)", float(d_), lu.get("d_mm"), tn[1] if tn else None))
    # A bench calibration has no hand-eye and no robot-world transform.
    poses: List[Tuple[str, F64, PoseSigma, Optional[F64]]] = [] if cal.is_bench else [
        ("X", cal.hand_cam, u.get("hand_cam", {}), truth.hand_cam if truth else None),
        ("Z", cal.base_board, u.get("base_board", {}), truth.base_board if truth else None),
    ]
    for label, m, tu, tm in poses:
        rv = stripecal.matrix_to_rotvec(m[:3, :3])
        trv = stripecal.matrix_to_rotvec(tm[:3, :3]) if tm is not None else None
        if trv is not None and np.linalg.norm(rv - trv) > np.pi:
            # near 180 deg a rotation has two rotation vectors: show the truth's branch
            rv = rv * (1.0 - 2.0 * np.pi / np.linalg.norm(rv))
        for i, a in enumerate("xyz"):
            out.append((f"{label} rotvec {a} (rad)", float(rv[i]), _at(tu.get("rotation_vector"), i),
                        float(trv[i]) if trv is not None else None))
        for i, a in enumerate("xyz"):
            out.append((f"{label} t{a} (mm)", float(m[i, 3]), _at(tu.get("translation_mm"), i),
                        float(tm[i, 3]) if tm is not None else None))
    return out


def write_report(
    out_dir: _Path,
    calibration: stripecal.Calibration,
    *,
    truth: Optional[stripecal.Truth] = None,
    points: Optional[npt.ArrayLike] = None,
    point_colour: Optional[npt.ArrayLike] = None,
    sections: Sequence[Tuple[str, str]] = (),
    title: str = "stripecal calibration report",
) -> Path:
    """Writes ``out_dir/index.html`` and its PNG figures; returns the HTML path.

    ``truth`` adds a true-value column; ``points`` (M, 3) mm adds the cloud figure,
    coloured by ``point_colour`` (M,) (e.g. each point's distance from the fitted sphere);
    ``sections`` are extra ``(heading, preformatted text)`` blocks (e.g. the demo's
    tables)."""
    plt = _pyplot()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cal = calibration
    figures = [
        f for f in (
            _circle_figure(plt, cal, out),
            _stripe_figure(plt, cal, out),
            _rms_figure(plt, cal, out),
            _hist_figure(plt, cal, out),
        ) if f
    ]
    if points is not None:
        p = np.asarray(points, np.float64).reshape(-1, 3)
        col = None if point_colour is None else np.asarray(point_colour, np.float64).ravel()
        f = _cloud_figure(plt, p, col, out)
        if f:
            figures.append(f)
    q = cal.quality
    summary = cal.summary
    method = summary["method"] if summary else "?"
    stripe_mm = summary["stripe_rms_mm"] if summary else None
    rows = parameter_rows(cal, truth)
    tr = []
    for name, value, sigma, true in rows:
        s = "" if sigma is None else f"{float(sigma):.3g}"
        t = "" if true is None else f"{true:.6f}"
        err = "" if true is None else f"{value - true:+.3g}"
        tr.append(f"<tr><td>{html.escape(name)}</td><td>{value:.6f}</td><td>{s}</td><td>{t}</td><td>{err}</td></tr>")
    views = cal.views
    vr = []
    for v in views:
        def f4(x: Optional[float]) -> str:
            return "" if x is None else f"{x:.4f}"
        bad = ' style="color:#b00"' if v["outlier"] or not v["used"] else ""
        found, left, sat = stripe_extraction_cells(v)
        off = v["stripe_off_plane"]
        vr.append(f"<tr{bad}><td>{v['view']}</td><td>{'yes' if v['used'] else 'no'}</td><td>{v['circles']}</td>"
                  f"<td>{found}</td><td>{left}</td><td>{'' if off is None else off}</td><td>{sat}</td>"
                  f"<td>{v['stripe_points']}</td><td>{f4(v['circle_rms_px'])}</td>"
                  f"<td>{f4(v['stripe_rms_px'])}</td><td>{html.escape(str(v['note'] or ''))}</td></tr>")
    warn = "".join(f"<li>{html.escape(str(w))}</li>" for w in cal.warnings)
    loo_html = _leave_one_out_html(cal)
    extra_sections = "".join(f"<h2>{html.escape(h)}</h2><pre>{html.escape(t)}</pre>" for h, t in sections)
    imgs = "".join(f'<figure><img src="{f}" alt="{f}"><figcaption>{f}</figcaption></figure>' for f in figures)
    doc = f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:1100px}} table{{border-collapse:collapse}}
td,th{{border:1px solid #ccc;padding:2px 8px;text-align:right}} td:first-child{{text-align:left}}
img{{max-width:100%}} figure{{margin:1em 0}}</style></head><body>
<h1>{html.escape(title)}</h1>
<p>method <b>{html.escape(method)}</b>, camera model {html.escape(cal.camera.distortion_model)},
{q['views_used']} views used. Residual RMS: target points <b>{q['target_rms_px']:.4f} px</b>,
stripe <b>{q['stripe_rms_px']:.4f} px</b> ({float(stripe_mm or float('nan')):.4f} mm){'' if cal.laser_plane is not None else ' (laser plane not estimated: ' + _no_plane_reason(cal) + ')'}.</p>
{checks_html(cal.quality)}
{('<h2>Warnings</h2><ul>' + warn + '</ul>') if warn else ''}
<h2>Parameters</h2>
<table><tr><th>parameter</th><th>value</th><th>1 sigma</th><th>true</th><th>error</th></tr>{''.join(tr)}</table>
<h2>Views</h2>
<table><tr><th>view</th><th>used</th><th>target points</th><th>stripe found</th><th>left out</th><th>off plane</th><th>saturated %</th><th>stripe points used</th><th>target RMS px</th><th>stripe RMS px</th><th>note</th></tr>{''.join(vr)}</table>
{_robot_pose_noise_html(cal)}
{_robot_html(cal)}
{loo_html}
{extra_sections}
<h2>Figures</h2>{imgs}
</body></html>
"""
    return write_html(out, doc)


def write_html(out: Path, doc: str) -> Path:
    """Writes ``out/index.html`` atomically (a temporary file renamed); returns its path."""
    path = out / "index.html"
    tmp = out / "index.html.tmp"
    tmp.write_text(doc, encoding="utf-8")
    os.replace(tmp, path)
    return path


def checks_html(q: Union[CalibrationQuality, ProfilerQuality]) -> str:
    """The quality gates' verdicts of a calibration's ``quality`` (a camera's or a line
    profiler's), and a banner when a failed calibration was kept."""
    checks = q["checks"]
    if not checks:
        return ""
    rows = []
    for c in checks:
        bad = ' style="color:#b00"' if not c["passed"] else ""
        views = ", ".join(str(v) for v in c["views"])
        rows.append(f"<tr{bad}><td>{html.escape(c['name'])}</td><td>{'passed' if c['passed'] else 'FAILED'}</td>"
                    f"<td>{html.escape(views)}</td><td style=\"text-align:left\">{html.escape(c['message'])}</td></tr>")
    banner = ('<p style="color:#fff;background:#b00;padding:0.5em"><b>ACCEPTED POOR</b>: this calibration failed '
              "a quality check and was kept with --accept-poor. Do not use it to accept or reject parts.</p>"
              if q["accepted_poor"] else "")
    return (f"<h2>Quality checks</h2>{banner}<table><tr><th>check</th><th>verdict</th><th>views</th>"
            f"<th>figures</th></tr>{''.join(rows)}</table>")


def _robot_pose_noise_html(cal: stripecal.Calibration) -> str:
    """The robot-pose noise section: the estimated noise (mm, deg), the image part's
    factor, the DH error size the covariance carries, and each view's correction and test
    (views above 4 disagree; those left out are listed)."""
    rn = cal.robot_pose_noise
    if rn is None:
        return ""

    def num(x: Optional[float], fmt: str) -> str:
        return "" if x is None else format(x, fmt)

    floor = [k for k, v in rn["at_floor"].items() if v]
    k = rn["image_factor"]
    km, kd = rn["kinematic_mm"], rn["kinematic_deg"]
    rows = []
    for v in rn["views"]:
        t = v["test"]
        bad = ' style="color:#b00"' if t is not None and t > 4.0 else ""
        rows.append(f"<tr{bad}><td>{v['view']}</td><td>{num(v['translation_mm'], '.4f')}</td>"
                    f"<td>{num(v['rotation_deg'], '.5f')}</td><td>{num(t, '.2f')}</td><td></td></tr>")
    for v in rn["left_out"]:
        rows.append(f"<tr style=\"color:#b00\"><td>{v['view']}</td><td>{num(v['translation_mm'], '.4f')}</td>"
                    f"<td>{num(v['rotation_deg'], '.5f')}</td><td>{num(v['test'], '.2f')}</td><td>left out</td></tr>")
    text = (f"<p>Each view's robot pose is corrected by its own small transform; the corrections' spread is the "
            f"robot-pose noise, one-sigma per flange component: <b>{num(rn['translation_mm'], '.3g')} mm</b>, "
            f"<b>{num(rn['rotation_deg'], '.3g')} deg</b>"
            + (f" (at floor: {html.escape(', '.join(floor))})" if floor else "") + ". "
            + (f"The part of each view's pose error its own image makes (detector biases, a board not quite flat, "
               f"a lens the model does not quite fit): {k:.3g} times the image's own pose precision. " if k is not None
               else "")
            + (f"DH errors of {km:.3g} mm / {kd:.3g} deg would explain the noise; what they would do to X and Z "
               f"is in the sigmas. " if km is not None and kd is not None else "")
            + "A view whose test is above 4 has a pose off by far more than the others' and is left out.</p>")
    return (f"<h2>Robot-pose noise</h2>{text}<table><tr><th>view</th><th>correction mm</th><th>correction deg</th>"
            f"<th>test</th><th></th></tr>{''.join(rows)}</table>")


def _robot_html(cal: stripecal.Calibration) -> str:
    """The robot calibration section (``--robot``): the DH corrections with their sigmas
    and the candidates held, with why."""
    rc = cal.robot_calibration
    if rc is None:
        return ""

    def num(x: Optional[float], fmt: str) -> str:
        return "" if x is None else format(x, fmt)

    est = "".join(
        f"<tr><td>{html.escape(e['name'])}</td><td>{num(e['correction'], '+.5f')}</td>"
        f"<td>{num(e['sigma'], '.5f')}</td></tr>"
        for e in rc["estimated"])
    held = "".join(f"<li>{html.escape(f['name'])}: {html.escape(f['reason'])}</li>" for f in rc["fixed"])
    return (
        f"<h2>Robot calibration ({html.escape(rc['mode'])})</h2><p>Corrections to rig.json's DH rows "
        "(degrees or mm), estimated with the rest; the refined rows are the calibration's robot.</p>"
        f"<table><tr><th>correction</th><th>value</th><th>1 sigma</th></tr>{est}</table>"
        + (f"<p>Held at rig.json's values:</p><ul>{held}</ul>" if held else "")
    )


def _leave_one_out_html(cal: stripecal.Calibration) -> str:
    """The leave-one-view-out section: the table, and which views disagree by how much."""
    loo = cal.leave_one_out
    if loo is None:
        return ""
    rows = []
    for v in loo["views"]:
        s = v["stripe_rms_mm"]
        bad = ' style="color:#b00"' if v["disagrees"] else ""
        rows.append(f"<tr{bad}><td>{v['view']}</td><td>{v['points']}</td><td>{v['board_rms_px']:.4f}</td>"
                    f"<td>{v['board_rms_mm']:.4f}</td><td>{'' if s is None else f'{s:.4f}'}</td>"
                    f"<td>{'disagrees' if v['disagrees'] else ''}</td></tr>")
    med_px = loo["median_board_rms_px"]
    bad_views = [v for v in loo["views"] if v["disagrees"]]
    if bad_views:
        verdict = "Views that disagree with the others (beyond 3 times the median): " + ", ".join(
            f"view {v['view']} ({v['board_rms_px']:.3f} px, {v['board_rms_px'] / med_px:.1f} times the median)"
            for v in bad_views) + "."
    else:
        verdict = "No view disagrees with the others (none beyond 3 times the median)."
    ms = loo["median_stripe_rms_mm"]
    how = (
        "Each view's board pose fitted to its own target points with the camera of the calibration solved "
        "without it (the fit's residuals), and its stripe points triangulated with that calibration's "
        "laser plane against that board plane (the bench: no robot pose)."
        if cal.is_bench else
        "Each view's target points predicted from its robot pose alone by the "
        "calibration solved without it, against the detected points; stripe points triangulated with the "
        "laser plane against the predicted board plane."
    )
    lb = loo.get("laser_board")
    laser_board = (
        "" if lb is None else
        f" Held-out laser-&gt;board distance (every stripe point of every view against the board plane "
        f"predicted by the calibration without its view; {lb['points']} points): median "
        f"<b>{lb['median_mm']:.4f} mm</b>, p95 <b>{lb['p95_mm']:.4f} mm</b>."
    )
    return (
        f"<h2>Leave-one-view-out</h2><p>{how} Median: <b>{med_px:.4f} px</b>, "
        f"<b>{loo['median_board_rms_mm']:.4f} mm</b> on the board"
        + ("" if ms is None else f", stripe <b>{ms:.4f} mm</b>") + f".{laser_board} {html.escape(verdict)}</p>"
        "<table><tr><th>view</th><th>points</th><th>board RMS px</th><th>board RMS mm</th>"
        f"<th>stripe RMS mm</th><th></th></tr>{''.join(rows)}</table>"
    )


__all__ = ["parameter_rows", "write_report"]
