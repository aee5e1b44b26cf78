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
    view["target_points"]                    # true imaged target points (N, 2)

Presets: ``hp3-paper`` (the paper's rig and 8 x 11 circle board), ``hp3-wide`` (a
wide-angle, distorted camera), ``hp3-chessboard`` and ``hp3-asymmetric`` (the paper's
rig with a chessboard or an asymmetric circle grid), ``hp3-sheet`` (a chessboard on a
large white sheet above the table, the laser beside the pattern, one image per view),
``hp3-profiler`` (a line profiler measuring a reference sphere; below). ``board.kind``
selects the target:
``"circles"``, ``"asymmetric_circles"`` or ``"chessboard"`` (with ``board.square_mm``).

For robot kinematic calibration: ``robot_error`` (one-sigma random DH errors drawn
from the seed: the true robot differs from rig.json's nominal one),
``poses.spread="wide"`` (views spread over the joints' feasible excursions; see
:func:`calibration_pose_set`), ``scan.table`` (a sweep over the bare table, written to
``scan_table/``) and :func:`surface_errors` (reconstructed points against the true
sphere, plate and table).

The bench mode (issue 17; ``bench={"enabled": True, ...}``, docs/twin.md): a fixed
sensor, the board placed by hand (``bench.views`` poses, tilts up to ``max_tilt_deg``,
``partial_views`` of them partly out of the image), no robot; :meth:`Twin.write` then
writes a bench dataset to ``out/calib`` (views.csv header ``board_image,laser_image``)
and, with ``bench.scan.enabled``, a fixed-sensor scan of a ball on a conveyor to
``out/scan`` (scan.csv header ``image``). ``bench.bow`` bends some views' board
(the true ``sag_mm`` in truth.json), ``bench.floor`` stands the board on a floor that
carries the laser line on. :meth:`Twin.bench_views` gives the true board poses.

The profiler mode (issue 18; preset ``hp3-profiler`` or ``profiler={"enabled": True,
...}``, docs/twin.md "The profiler mode"): a calibrated line PROFILER on the HP3's flange
measures a reference sphere on a stand above a table; :meth:`Twin.write` writes a
profile dataset to ``out/calib`` (rig.json ``sensor.kind = "profiler"``, views.csv
``profile,q1..q6``, ``profiles/view_NNN.csv`` with ``x_mm,z_mm,intensity``) and a scan
across the ball to ``out/scan``; :func:`profiler_truth` reads their truth.json back.
Knobs of ``profiler``: ``line_length_mm`` (90) and ``spacing_mm`` (0.03: 3000 samples,
x centred on 0), the measuring range ``z_min_mm``/``z_max_mm`` (150..350; hits outside
are gaps), ``noise_z_mm`` (0.01, Gaussian on z), ``gap_fraction`` (0.02 random
dropouts), ``spike_fraction`` (0.01) of magnitude ``spike_min_mm``..``spike_max_mm``
(0.5..3, random sign), ``invalid_z`` (-99999.9999; gaps are written as an empty z,
``nan`` and this sentinel in turn), ``intensity`` (a third column), the sphere
(``sphere_diameter_mm`` 80, ``sphere_center_mm`` base frame, ``stand_height_mm`` 60 above
the table, ``stand_diameter_mm`` 20), ``diameter_declared`` (``True``: rig.json declares
the true diameter, ``False``: ``null``, a number: that one), the true ``hand_sensor``
(``T_hand_sensor``: ~100 mm below the flange, looking along the flange's z), the views
(``views`` 15; the sphere centre in the sensor frame: stand-off ``standoff_min_mm`` ..
``standoff_max_mm`` (200..250), place along the line within ``+-place_max_mm`` (15),
plane offset ``|y|`` in ``offset_min_frac`` .. ``offset_max_frac`` (0.1..0.75) of the
radius with alternating sign; tilts ``tilt_min_deg`` .. ``tilt_max_deg`` (10..30) about
a horizontal axis and ``+-spin_max_deg`` (30) about the sensor's z),
``degenerate`` (``"none"``, ``"same_standoff"``, ``"same_place"``, ``"same_offset"``)
with ``near_degenerate_mm`` (the fixed coordinate varies only over this range),
``max_joint_delta_deg``, ``poses`` (``"joints"`` or ``"flange"``: the pose columns
``pose_columns``, default ``"quaternion"``), ``scan_frames`` (60, 0: no scan) and
``scan_step_mm`` (1). ``robot_error`` draws the true robot as in the camera twin
(rig.json keeps the nominal one).

Unknown keys are an error, so a misspelt knob never goes unnoticed. All rendering runs
in Rust (``stripecal._core``); this module only converts configurations.
"""

from __future__ import annotations

import copy
import json
import os
from typing import Any, Callable, Dict, List, Optional, Tuple, Union, cast

import numpy as np
import numpy.typing as npt

from stripecal._core import Board, Camera, Robot, Truth
from stripecal._core import Twin as _CoreTwin
from stripecal._core import load_truth, sim_config, sim_presets, sim_surface_errors
from stripecal.types import (
    BenchView,
    ProfilerTruth,
    SimConfig,
    SimPose,
    TwinSummary,
    VerifyScan,
    ViewRender,
)

__all__ = ["Twin", "calibration_pose_set", "preset", "presets", "profiler_truth", "surface_errors"]


def presets() -> List[str]:
    """Names of the built-in presets (``hp3-paper``: the paper's rig; ``hp3-wide``: a
    wide-angle, strongly distorted camera with 15 poses; ``hp3-chessboard``: the paper's
    rig with a 7 x 10 inner-corner chessboard of 4.8 mm squares; ``hp3-asymmetric``: the
    paper's rig with an 11 x 8 asymmetric circle grid, pitch 7 mm, circles 2.5 mm;
    ``hp3-sheet``: an 8 x 9 inner-corner chessboard of 4 mm squares on a white sheet
    reaching 20 mm beyond its outer corners and lying 4 mm above the table, laser and
    board in one image, 15 poses with the stripe mostly on the sheet beside the pattern
    and across the sheet's edge onto the table; ``hp3-profiler``: the HP3 carrying a
    calibrated line profiler that measures an 80 mm sphere, 15 views, joint readings,
    a 60-profile scan)."""
    return list(sim_presets())


def preset(name: str = "hp3-paper", overrides: Optional[SimConfig] = None, **knobs: Any) -> SimConfig:
    """The full configuration of preset ``name`` with ``overrides`` (a nested dict) and
    top-level ``knobs`` (e.g. ``seed=3``, ``imaging={"noise_gray": 2}``) merged over it.
    Nested dicts merge key by key; anything else replaces."""
    merged: Dict[str, object] = dict(overrides or {})
    merged.update(knobs)
    text = sim_config(name, json.dumps(merged) if merged else None)
    cfg: SimConfig = json.loads(text)
    return cfg


class Twin:
    """A rig's digital twin (see the module docstring). ``config`` is a full
    configuration dict (from :func:`preset`) or a preset name."""

    def __init__(self, config: Union[SimConfig, str] = "hp3-paper") -> None:
        cfg = preset(config) if isinstance(config, str) else config
        self._core = _CoreTwin(json.dumps(cfg))

    @property
    def config(self) -> SimConfig:
        """The full configuration (a fresh dict)."""
        cfg: SimConfig = json.loads(self._core.config_json)
        return cfg

    @property
    def camera(self) -> Camera:
        """The true camera."""
        return self._core.camera

    @property
    def board(self) -> Board:
        """The target (its ``kind``: ``circles``, ``asymmetric_circles`` or
        ``chessboard``)."""
        return self._core.board

    @property
    def board_kind(self) -> str:
        """The target's kind: ``"circles"``, ``"asymmetric_circles"`` or
        ``"chessboard"``."""
        return str(self._core.board.kind)

    @property
    def robot_nominal(self) -> Robot:
        """The nominal DH table (what rig.json holds)."""
        return self._core.robot_nominal

    @property
    def robot_true(self) -> Robot:
        """The true DH table: nominal plus ``dh_errors``."""
        return self._core.robot_true

    @property
    def hand_cam(self) -> npt.NDArray[np.float64]:
        """True ``T_hand_cam`` (4, 4)."""
        return self._core.hand_cam

    @property
    def base_board(self) -> npt.NDArray[np.float64]:
        """True ``T_base_board`` (4, 4)."""
        return self._core.base_board

    @property
    def laser_plane(self) -> Tuple[npt.NDArray[np.float64], float]:
        """True laser plane ``(normal, d_mm)`` in the camera frame: ``n . p = d``."""
        return self._core.laser_plane

    @property
    def stripe_direction(self) -> str:
        """``"rows"`` or ``"cols"``: how the stripe runs in the images."""
        return self._core.stripe_direction

    def truth(self, with_sphere: bool = True) -> Truth:
        """The true parameters, as written to truth.json (without per-image keys)."""
        return self._core.truth(with_sphere)

    def calibration_poses(self) -> List[SimPose]:
        """The calibration poses: ``q_deg`` (encoder readings), ``standoff_mm``,
        ``tilt_deg``, ``stripe_chord_mm``; explicit ones or sampled by seed."""
        return self._core.calibration_poses()

    def scan_poses(self) -> npt.NDArray[np.float64]:
        """Encoder readings (N, J) of the scan sweep over the ball."""
        return self._core.scan_poses()

    def table_scan_poses(self) -> npt.NDArray[np.float64]:
        """Encoder readings (N, J) of the sweep over the bare table (``scan.table``;
        (0, J) when off): away from the board and the ball, at the home pose's
        orientation, ``scan.table_offset_mm`` from the board centre."""
        return self._core.table_scan_poses()

    def verify_scans(self) -> List[VerifyScan]:
        """The verification scans of ``verify.*`` (written to ``out/verify`` by
        :meth:`write` when ``verify.enabled``): the ball bar's positions, then the
        plate's; per scan ``name`` (its folder), ``artefact`` (``"bar"`` or
        ``"plate"``), ``poses`` (N, J), the true ``spheres`` (bars) or ``plane``
        (plates), base frame. Computed whether or not ``verify.enabled``."""
        return self._core.verify_scans()

    def bench_views(self) -> List[BenchView]:
        """The bench mode's board poses (``bench.*``; deterministic per seed): per view the
        true ``cam_board`` (4, 4), ``standoff_mm``, ``tilt_deg``, ``partial``, the true
        ``sag_mm`` (0: flat) and ``bow_axis_deg``, the floor plane (``floor_normal``,
        ``floor_d_mm``) with ``bench.floor``."""
        return self._core.bench_views()

    def render_view(self, q: npt.ArrayLike, index: int = 0) -> ViewRender:
        """Renders a calibration view at encoder readings ``q`` (degrees). Keys:
        ``board_image``, ``laser_image`` (None in single-image mode), ``target_indices``
        (N, 2) (row, col) and ``target_points`` (N, 2): the true imaged target points
        (circles: outline centroids, whole circle in the image; chessboard corners: the
        projected corner, inside the image); the same data as ``circle_indices`` and
        ``circle_centers`` (the historical names); ``circle_centers_projected`` (the
        projected points: for a chessboard equal to the truth), ``stripe_points``
        (M, 2) and per-point ``stripe_surface``, ``stripe_incidence_deg``,
        ``stripe_view_deg``, ``stripe_edge_mm``, ``stripe_slope``,
        ``stripe_points_cam`` (M, 3), ``base_cam``.
        ``index`` selects the noise stream (views of one dataset differ by index).
        The keys are documented field by field in :class:`stripecal.types.ViewRender`."""
        return self._core.render_view(q, index)

    def render_scan_frame(self, q: npt.ArrayLike, index: int = 0) -> ViewRender:
        """Renders a scan frame (the ball on the table) at ``q``; keys as
        :meth:`render_view` (``laser_image`` holds the frame)."""
        return self._core.render_scan_frame(q, index)

    def write(self, out: Union[str, "os.PathLike[str]"], progress: Optional[Callable[[str, int, int], Any]] = None) -> TwinSummary:
        """Renders and writes ``out/calib``, ``out/scan``, with ``scan.table``
        ``out/scan_table`` and with ``verify.enabled`` ``out/verify`` (each written under a
        temporary name, then renamed); returns a summary dict (``board_kind``, per view
        ``circles_visible``: the imaged target points, whatever the kind; every key in
        :class:`stripecal.types.TwinSummary`)."""
        return self._core.write(out, progress)


def calibration_pose_set(
    config: Union[SimConfig, str],
    count: int,
    spread: str = "wide",
    seed: Optional[int] = None,
) -> npt.NDArray[np.float64]:
    """A plan of ``count`` calibration poses for the robot, board and camera of
    ``config`` (a configuration dict or a preset name): joint readings in degrees,
    shape ``(count, dof)``, every one checked against the views' constraints (board in
    view with ``poses.margin_px``, stand-off, tilt, laser incidence, stripe across the
    pattern, joint excursions within ``poses.max_joint_delta_deg`` of
    ``poses.home_q_deg``). ``spread="wide"`` spreads the poses over every joint's
    feasible excursion (each joint's extremes, then farthest apart in joint space);
    ``"local"`` is the twin's default sampler. ``seed`` replaces the configuration's.
    The poses are solved on the configuration's true robot: its DH table when
    ``dh_errors`` and ``robot_error`` are zero (a plan for a real robot: give its table).
    Deterministic; no image is rendered."""
    cfg = copy.deepcopy(preset(config) if isinstance(config, str) else config)
    cfg["poses"]["count"] = int(count)
    cfg["poses"]["spread"] = spread
    cfg["poses"]["explicit_q_deg"] = None
    if seed is not None:
        cfg["seed"] = int(seed)
    twin = Twin(cfg)
    dof = len(cfg["robot"]["joints"])
    q = [np.asarray(p["q_deg"], dtype=np.float64) for p in twin.calibration_poses()]
    return np.array(q, dtype=np.float64).reshape(len(q), dof)


def surface_errors(
    points: npt.ArrayLike, truth: Union[Truth, Twin, str, "os.PathLike[str]"]
) -> npt.NDArray[np.float64]:
    """Signed distances (mm) of base-frame points ``(N, 3)`` to the nearest true surface
    of the twin's world: the sphere (if the truth has one), the plate the target is
    printed on, the table plane (truth.json's ``table``: ``n . p = d`` in the base frame,
    ``n`` up); positive outside the ball and above the plate or table. ``truth`` is a
    :class:`stripecal.Truth` (``load_truth``), a truth.json path or a :class:`Twin`
    (its truth with the sphere). Points far from every surface are returned too (the
    caller decides); returns ``(N,)``."""
    if isinstance(truth, Twin):
        t = truth.truth(True)
    elif isinstance(truth, (str, os.PathLike)):
        t = load_truth(truth)
    else:
        t = truth
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out: npt.NDArray[np.float64] = np.asarray(sim_surface_errors(pts, t), dtype=np.float64)
    return out


def profiler_truth(path: Union[str, "os.PathLike[str]"]) -> ProfilerTruth:
    """truth.json of a profiler twin (``calib/`` or ``scan/``; ``path`` is the file or
    its folder): the true ``hand_cam`` (``T_hand_sensor``), the ``sphere`` (base frame),
    the TRUE ``robot`` (with joint readings), the ``table`` and ``stand``, and per
    profile (``views`` or ``frames``) the sphere centre in the sensor frame. Raises
    ``ValueError`` for a file that is not a profiler twin's truth."""
    p = os.fspath(path)
    if os.path.isdir(p):
        p = os.path.join(p, "truth.json")
    with open(p, encoding="utf-8") as f:
        data = json.load(f)
    if not isinstance(data, dict) or data.get("format") != "stripecal/truth@1":
        raise ValueError(f"{p}: not a stripecal truth.json (format stripecal/truth@1)")
    sensor = data.get("sensor")
    if not isinstance(sensor, dict) or sensor.get("kind") != "profiler":
        raise ValueError(f"{p}: not the truth of a profiler twin (sensor.kind is not \"profiler\")")
    for key in ("hand_cam", "sphere"):
        if key not in data:
            raise ValueError(f"{p}: key {key!r} missing")
    return cast(ProfilerTruth, data)
