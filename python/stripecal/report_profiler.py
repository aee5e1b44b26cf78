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
from typing import Any, List, Mapping, Optional, Union

import stripecal
from stripecal.cli_profiler import _list, _map, _num, mirror_text, parameter_rows
from stripecal.report import _pyplot, _save, checks_html, write_html

_Path = Union[str, "os.PathLike[str]"]


def _views(cal: stripecal.ProfilerCalibration) -> List[Mapping[str, object]]:
    v = cal.extra.get("views")
    return [_map(x) for x in _list(v)]


def _rms_figure(plt: Any, cal: stripecal.ProfilerCalibration, out: Path) -> Optional[str]:
    views = [v for v in _views(cal) if v.get("used")]
    if not views:
        return None
    loo_views = _map(cal.extra.get("leave_one_out")).get("views")
    loo = {int(str(_map(x).get("view"))): _num(_map(x).get("rms_mm")) for x in _list(loo_views)}
    ids = [int(str(v.get("view"))) for v in views]
    fig, ax = plt.subplots(figsize=(8, 3.2))
    xs = range(len(ids))
    ax.bar([x - 0.2 for x in xs], [_num(v.get("rms_mm")) or 0.0 for v in views], 0.4, label="in the fit")
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
    for v in _views(cal):
        c = v.get("centre_in_sensor_mm")
        if v.get("used") and isinstance(c, list) and len(c) == 3:
            p = [float(c[0]), float(c[1]), float(c[2])]
            s = _num(v.get("side"))
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
    e = cal.extra
    prm = "".join(f"<tr><td>{html.escape(n)}</td><td>{v:.6f}</td><td>{'' if s is None else f'{float(s):.3g}'}</td></tr>"
                  for n, v, s in parameter_rows(cal))
    vr = []
    for v in _views(cal):
        bad = ' style="color:#b00"' if not v.get("used") else ""
        rms = _num(v.get("rms_mm"))
        vr.append(f"<tr{bad}><td>{v.get('view')}</td><td>{'yes' if v.get('used') else 'no'}</td><td>{v.get('points')}</td>"
                  f"<td>{v.get('gaps')}</td><td>{v.get('sphere_points')}</td><td>{v.get('rejected')}</td>"
                  f"<td>{'' if rms is None else f'{rms:.4f}'}</td><td style=\"text-align:left\">{html.escape(str(v.get('note') or ''))}</td></tr>")
    warnings = e.get("warnings")
    warn = "".join(f"<li>{html.escape(str(w))}</li>" for w in _list(warnings))
    m = _map(e.get("mirror"))
    dc = _map(e.get("diameter_check"))
    loo = _map(e.get("leave_one_out"))
    facts = []
    if m:
        facts.append(mirror_text(m))
    if dc:
        facts.append(f"diameter check: declared {_num(dc.get('declared_mm'))} mm, the profiles say {_num(dc.get('estimate_mm'))} "
                     f"+- {_num(dc.get('sigma_mm'))} mm{' (DISAGREES)' if dc.get('disagrees') else ''}")
    if loo:
        facts.append(f"leave-one-view-out: median held-out profile RMS {_num(loo.get('median_rms_mm'))} mm")
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
