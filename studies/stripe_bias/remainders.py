"""The evidence behind the sphere stripe-bias correction's remainder bound
(``NEGLECTED_FRACTION`` in crates/stripecal/src/reconstruct/fit/stripe_bias/mod.rs):
the twin's ball scans, reconstructed with the TRUE calibration and corrected, over
several seeds per condition; the remainder of each quantity as a percentage of its
correction, mean over the seeds and its standard error.

    python studies/stripe_bias/remainders.py runs --seeds 1-6 > runs.json
    cargo run --release --manifest-path studies/stripe_bias/Cargo.toml --bin sweep \\
        -- runs.json > sweep.log                        # ~25-40 s a scan on two cores
    python studies/stripe_bias/remainders.py table sweep.log

The runs print one ``SWEEP {json}`` line each (src/bin/sweep.rs). With ``--true-model``
after ``--`` the correction takes the twin's true sheet sigma, PSF sigma and emitter
instead of estimating them: the remainder is then the model's own.
"""

from __future__ import annotations

import argparse
import collections
import json
import sys
from typing import Any, Dict, List, Tuple

import numpy as np

CONDITIONS: Dict[str, Tuple[str, Dict[str, Any]]] = {
    "paper, noise 1": ("hp3-paper", {}),
    "paper, noise 2": ("hp3-paper", {"imaging": {"noise_gray": 2.0}}),
    "wide, noise 1": ("hp3-wide", {}),
    "wide, noise 2": ("hp3-wide", {"imaging": {"noise_gray": 2.0}}),
    "paper, sheet sigma 0.2 mm": ("hp3-paper", {"imaging": {"laser_sigma_mm": 0.2}}),
    "paper, 25.4 mm ball": ("hp3-paper", {"scan": {"sphere_diameter_mm": 25.4}}),
    "paper, PSF 1 px": ("hp3-paper", {"imaging": {"psf_sigma_px": 1.0}}),
}


def seeds(text: str) -> List[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def runs(a: argparse.Namespace) -> None:
    out = []
    for name in a.only or CONDITIONS:
        preset, over = CONDITIONS[name]
        out += [[preset, {**over, "seed": s}, 1] for s in seeds(a.seeds)]
    print(json.dumps(out))


def table(a: argparse.Namespace) -> None:
    groups: Dict[Tuple[str, str], List[Dict[str, Any]]] = collections.defaultdict(list)
    for path in a.logs:
        for line in open(path):
            if line.startswith("SWEEP "):
                r = json.loads(line[6:])
                over = {k: v for k, v in r["overrides"].items() if k != "seed"}
                groups[(r["preset"], json.dumps(over, sort_keys=True))].append(r)
    print("| rig | overrides | seeds | diameter's correction um | remainder % (mean +- s.e.) "
          "| centre x % | centre z % |")
    print("|---|---|---|---|---|---|---|")
    for (preset, over), rs in groups.items():
        n = len(rs)
        ch = np.array([r["diameter_change_mm"] for r in rs])
        d = np.array([r["diameter_error_mm"][1] for r in rs]) / np.abs(ch) * 100
        cc = np.array([r["center_change_mm"] for r in rs])
        ce = np.array([r["center_error_mm"][1] for r in rs]) / np.abs(cc) * 100

        def ms(v: np.ndarray) -> str:
            se = v.std(ddof=1) / np.sqrt(n) if n > 1 else float("nan")
            return f"{v.mean():+.1f} +- {se:.1f}"

        print(f"| {preset} | {over} | {n} | {ch.mean() * 1e3:+.2f} | {ms(d)} | {ms(ce[:, 0])} | {ms(ce[:, 2])} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("runs", help="print the sweep's runs (JSON) for the conditions")
    r.add_argument("--seeds", default="1-6", help="first-last")
    r.add_argument("--only", nargs="*", choices=list(CONDITIONS), help="these conditions only")
    t = sub.add_parser("table", help="the remainders from sweep logs")
    t.add_argument("logs", nargs="+")
    a = ap.parse_args()
    {"runs": runs, "table": table}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())
