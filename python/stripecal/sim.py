"""The digital twin: render calibration datasets and ball scans with known truth.

A twin is described by a configuration: a nested dict of every knob (camera, laser
plane, hand-eye ``hand_cam``, robot-world ``base_board``, robot DH table and DH errors,
board, poses, imaging: noise, PSF, bit depth, single-image mode..., scan). Start from a
preset and override what you need::

    import stripecal.sim as sim
    cfg = sim.preset("hp3-paper", seed=3, imaging={"noise_gray": 2.0})
    twin = sim.Twin(cfg)
    summary = twin.write("out")              # out/calib and out/scan, per spec/DATASET.md
    view = twin.render_view(twin.calibration_poses()[0]["q_deg"])
    view["board_image"]                      # (H, W) uint8 numpy array
    view["circle_centers"]                   # true imaged-circle centres (N, 2)

Unknown keys are an error, so a misspelt knob never goes unnoticed. All rendering runs
in Rust (``stripecal._core``); this module only converts configurations.
"""

from __future__ import annotations

import json
from typing import Any, Dict, List, Optional

from stripecal._core import Twin as _CoreTwin
from stripecal._core import sim_config, sim_presets

__all__ = ["Twin", "preset", "presets"]


def presets() -> List[str]:
    """Names of the built-in presets (``hp3-paper``: the paper's rig; ``hp3-wide``: a
    wide-angle, strongly distorted camera with 15 poses)."""
    return list(sim_presets())


def preset(name: str = "hp3-paper", overrides: Optional[Dict[str, Any]] = None, **knobs: Any) -> Dict[str, Any]:
    """The full configuration of preset ``name`` with ``overrides`` (a nested dict) and
    top-level ``knobs`` (e.g. ``seed=3``, ``imaging={"noise_gray": 2}``) merged over it.
    Nested dicts merge key by key; anything else replaces."""
    merged: Dict[str, Any] = dict(overrides or {})
    merged.update(knobs)
    text = sim_config(name, json.dumps(merged) if merged else None)
    cfg: Dict[str, Any] = json.loads(text)
    return cfg


class Twin:
    """A rig's digital twin (see the module docstring). ``config`` is a full
    configuration dict (from :func:`preset`) or a preset name."""

    def __init__(self, config: "Dict[str, Any] | str" = "hp3-paper") -> None:
        cfg = preset(config) if isinstance(config, str) else config
        self._core = _CoreTwin(json.dumps(cfg))

    @property
    def config(self) -> Dict[str, Any]:
        """The configuration (a fresh dict)."""
        cfg: Dict[str, Any] = json.loads(self._core.config_json)
        return cfg

    def __getattr__(self, name: str) -> Any:
        # camera, board, robot_nominal, robot_true, hand_cam, base_board, laser_plane,
        # stripe_direction, truth(), calibration_poses(), scan_poses(), render_view(),
        # render_scan_frame(), write(): see stripecal._core.Twin.
        return getattr(self._core, name)
