"""The HTML report of an acceptance test (``stripecal verify --report DIR``): the table
of every measured value with its expanded uncertainty and verdict, the summary per
characteristic and one figure (each value with its U as an error bar against the MPE).
Needs matplotlib (the ``report`` extra)."""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any, List, Union

from stripecal.report import _pyplot, _save, write_html
from stripecal.cli_measure import TITLES, verdict
from stripecal.types import VerifyReport

_Path = Union[str, "os.PathLike[str]"]

_TITLES = TITLES


def _figure(plt: Any, r: VerifyReport, out: Path) -> str:
    keys = [k for k in _TITLES if any(row["characteristic"] == k for row in r["rows"])]
    fig, axes = plt.subplots(1, max(len(keys), 1), figsize=(4.2 * max(len(keys), 1), 3.4), squeeze=False)
    for ax, key in zip(axes[0], keys):
        rows = [row for row in r["rows"] if row["characteristic"] == key]
        x = list(range(len(rows)))
        v = [row["budget"]["value_mm"] for row in rows]
        u = [row["budget"]["expanded_mm"] for row in rows]
        colours = ["#2a7" if row["conforms"] else ("#d90" if row["passed"] else "#c22") for row in rows]
        ax.errorbar(x, v, yerr=u, fmt="none", ecolor="#555", capsize=3)
        ax.scatter(x, v, c=colours, zorder=3)
        mpe = rows[0]["mpe_mm"]
        ax.axhline(mpe, color="#c22", lw=1)
        if key in ("probing_size", "sphere_spacing"):
            ax.axhline(-mpe, color="#c22", lw=1)
        ax.axhline(0, color="#999", lw=0.5)
        ax.set_title(_TITLES[key], fontsize=9)
        ax.set_xticks(x)
        ax.set_xticklabels([f"{row['scan']}\n{row['artefact']}" for row in rows], fontsize=6, rotation=60)
        ax.set_ylabel("mm")
    return _save(plt, fig, out, "verify.png")


def write_verify_report(out_dir: _Path, report: VerifyReport, *, title: str = "stripecal acceptance test") -> Path:
    """Writes ``out_dir/index.html`` and ``verify.png``; returns the HTML path."""
    plt = _pyplot()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig = _figure(plt, report, out)
    tr: List[str] = []
    for row in report["rows"]:
        b = row["budget"]
        style = "" if row["passed"] else ' style="color:#b00"'
        tr.append(f"<tr{style}><td>{html.escape(row['symbol'])}</td><td>{html.escape(row['scan'])}</td>"
                  f"<td>{html.escape(row['artefact'])}</td><td>{b['value_mm']:+.5f}</td><td>{b['expanded_mm']:.5f}</td>"
                  f"<td>{b['random_mm']:.2e}</td><td>{b['calibration_mm']:.2e}</td><td>{b['robot_mm']:.2e}</td>"
                  f"<td>{b['systematic_mm']:.2e}</td><td>{row['mpe_mm']:.4f}</td><td>{verdict(row)}</td></tr>")
    sr: List[str] = []
    for key, name in _TITLES.items():
        s = report["summary"].get(key)
        if s is None:
            sr.append(f"<tr><td>{name}</td><td colspan=5>not measured</td></tr>")
            continue
        sr.append(f"<tr><td>{name}</td><td>{s['worst_mm']:+.5f}</td><td>{s['expanded_mm']:.5f}</td>"
                  f"<td>{s['mpe_mm']:.4f}</td><td>{s['measurements']}</td><td>{verdict(s)}</td></tr>")
    doc = f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:1100px}} table{{border-collapse:collapse}}
td,th{{border:1px solid #ccc;padding:2px 8px;text-align:right}} td:first-child{{text-align:left}}
img{{max-width:100%}}</style></head><body>
<h1>{html.escape(title)}</h1>
<p>Acceptance test <b>{'PASSED' if report['passed'] else 'FAILED'}</b>. pass: |value| &le; MPE;
conforms: |value| + U &le; MPE (ISO 14253-1). U: expanded uncertainty, k = 2; the parts are standard
uncertainties in mm.</p>
<h2>Characteristics</h2>
<table><tr><th>characteristic</th><th>worst mm</th><th>U mm</th><th>MPE mm</th><th>n</th><th>verdict</th></tr>{''.join(sr)}</table>
<h2>Measurements</h2>
<table><tr><th></th><th>scan</th><th>artefact</th><th>value mm</th><th>U mm</th><th>random</th><th>calibration</th>
<th>robot</th><th>systematic</th><th>MPE mm</th><th>verdict</th></tr>{''.join(tr)}</table>
<h2>Figure</h2><img src="{fig}" alt="{fig}">
</body></html>
"""
    return write_html(out, doc)
