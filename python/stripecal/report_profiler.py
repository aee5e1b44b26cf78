"""HTML report of a line profiler's calibration (issue 18), with PNG figures.

Needs matplotlib (``pip install 'stripecal[report]'``). It draws what the calibration
recorded (calibration.json's keys; docs/profiler.md) and adds no numerics of its own.

Figures:

- ``profile_rms.png``: per profile, the RMS distance of its sphere points from the
  fitted sphere and its leave-one-out figure (against the sphere the other views predict
  from its robot pose);
- ``centres.png``: the sphere's centre as the sensor saw it in each view (place along
  the line x, offset from the laser plane y, stand-off z), the two sides marked: how far
  the poses are from the one-plane sets that leave the mirror undecided.
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any, Optional, Union

import stripecal
from stripecal.cli_profiler import mirror_text, parameter_rows
from stripecal.report import _pyplot, _save, checks_html, write_html

_Path = Union[str, "os.PathLike[str]"]


def _rms_figure(plt: Any, cal: stripecal.ProfilerCalibration, out: Path) -> Optional[str]:
    views = [v for v in cal.views if v["used"]]
    if not views:
        return None
    held = cal.leave_one_out
    loo = {x["view"]: x["rms_mm"] for x in (held["views"] if held else [])}
    ids = [v["view"] for v in views]
    fig, ax = plt.subplots(figsize=(8, 3.2))
    xs = range(len(ids))
    ax.bar([x - 0.2 for x in xs], [v["rms_mm"] or 0.0 for v in views], 0.4, label="in the fit")
    if loo:
        ax.bar([x + 0.2 for x in xs], [loo.get(i) or 0.0 for i in ids], 0.4, label="held out")
    ax.set_xticks(list(xs))
    ax.set_xticklabels([str(i) for i in ids])
    ax.set_xlabel("view")
    ax.set_ylabel("RMS distance from the sphere, mm")
    ax.legend()
    return _save(plt, fig, out, "profile_rms.png")


def _centres_figure(plt: Any, cal: stripecal.ProfilerCalibration, out: Path) -> Optional[str]:
    pts = []  # (centre, side): the side recorded (+1 / -1; y >= 0 for a view without one)
    for v in cal.views:
        c = v["centre_in_sensor_mm"]
        if v["used"] and c is not None and len(c) == 3 and None not in c:
            p = [float(x or 0.0) for x in c]
            s = v["side"]
            pts.append((p, (p[1] >= 0) if s is None else (s > 0)))
    if not pts:
        return None
    fig, axs = plt.subplots(1, 2, figsize=(9, 3.6))
    for ax, (i, j, a, b) in zip(axs, [(0, 2, "x (along the line)", "z (stand-off)"),
                                       (0, 1, "x (along the line)", "y (offset from the laser plane)")]):
        for side, colour in ((1, "tab:blue"), (-1, "tab:red")):
            sel = [p for p, up in pts if up == (side > 0)]
            if sel:
                ax.scatter([p[i] for p in sel], [p[j] for p in sel], c=colour, s=18,
                           label="y > 0" if side > 0 else "y < 0")
        ax.set_xlabel(f"{a}, mm")
        ax.set_ylabel(f"{b}, mm")
        ax.legend(fontsize=8)
    fig.suptitle("the sphere's centre as the sensor saw it")
    return _save(plt, fig, out, "centres.png")


def write_profiler_report(out_dir: _Path, calibration: stripecal.ProfilerCalibration,
                          *, title: str = "stripecal: line profiler calibration") -> Path:
    """Writes ``out_dir/index.html`` and its PNG figures; returns the HTML path."""
    plt = _pyplot()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cal = calibration
    figures = [f for f in (_rms_figure(plt, cal, out), _centres_figure(plt, cal, out)) if f]
    q = cal.quality
    prm = "".join(f"<tr><td>{html.escape(n)}</td><td>{v:.6f}</td><td>{'' if s is None else f'{float(s):.3g}'}</td></tr>"
                  for n, v, s in parameter_rows(cal))
    vr = []
    for v in cal.views:
        bad = ' style="color:#b00"' if not v["used"] else ""
        rms = v["rms_mm"]
        vr.append(f"<tr{bad}><td>{v['view']}</td><td>{'yes' if v['used'] else 'no'}</td><td>{v['points']}</td>"
                  f"<td>{v['gaps']}</td><td>{v['sphere_points']}</td><td>{v['rejected']}</td>"
                  f"<td>{'' if rms is None else f'{rms:.4f}'}</td><td style=\"text-align:left\">{html.escape(str(v['note'] or ''))}</td></tr>")
    warn = "".join(f"<li>{html.escape(str(w))}</li>" for w in cal.warnings)
    m = cal.mirror
    dc = cal.diameter_check
    loo = cal.leave_one_out
    facts = []
    if m:
        facts.append(mirror_text(m))
    if dc:
        facts.append(f"diameter check: declared {dc['declared_mm']} mm, the profiles say {dc['estimate_mm']} "
                     f"+- {dc['sigma_mm']} mm{' (DISAGREES)' if dc['disagrees'] else ''}")
    if loo:
        facts.append(f"leave-one-view-out: median held-out profile RMS {loo['median_rms_mm']} mm")
    imgs = "".join(f'<figure><img src="{f}" alt="{f}"><figcaption>{f}</figcaption></figure>' for f in figures)
    doc = f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:1100px}} table{{border-collapse:collapse}}
td,th{{border:1px solid #ccc;padding:2px 8px;text-align:right}} td:first-child{{text-align:left}}
img{{max-width:100%}} figure{{margin:1em 0}}</style></head><body>
<h1>{html.escape(title)}</h1>
<p>{q['views_used']} profiles used; profile RMS <b>{q['profile_rms_mm']:.4f} mm</b>.</p>
<ul>{''.join(f'<li>{html.escape(x)}</li>' for x in facts)}</ul>
{checks_html(q)}
{('<h2>Warnings</h2><ul>' + warn + '</ul>') if warn else ''}
<h2>Parameters</h2>
<table><tr><th>parameter</th><th>value</th><th>1 sigma</th></tr>{prm}</table>
<h2>Profiles</h2>
<table><tr><th>view</th><th>used</th><th>points</th><th>gaps</th><th>sphere points</th><th>rejected</th><th>RMS mm</th><th>note</th></tr>{''.join(vr)}</table>
<h2>Figures</h2>{imgs}
</body></html>
"""
    return write_html(out, doc)
