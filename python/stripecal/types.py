"""Typed records of the dicts that stripecal returns (and accepts).

The Rust extension ``stripecal._core`` returns plain ``dict`` objects; the classes here
are :class:`typing.TypedDict` declarations of those dicts, so that a type checker knows
every key and its type. They describe, they do not convert: at run time the values are
the same dicts as ever (``isinstance(x, dict)``), and nothing in the package builds one of
these classes. Each field is documented by the string literal that follows it.

Conventions (frames, units, pixel centres): docs/conventions.md. Arrays are numpy arrays
(``F64``: float64) with the shapes given in the field docs.

Typing notes:

- The stub of the extension (``_core.pyi``) imports these classes, so they must exist at
  run time; this module is plain Python (no ``from __future__ import annotations``) and
  imports nothing from the extension but :class:`~stripecal.Camera`.
- The pure-Python modules of the package (this one, ``io``, ``vision``, ``calib``,
  ``reconstruct``, ``sim``, ``cli``, ``report``) are typed inline and re-export with
  ``__all__``: they need no ``.pyi`` of their own (``py.typed`` marks the package).
- Records read from a file a user may have written (calibration.json's ``uncertainty``
  and extra keys, a sphere fit's extra keys) are ``total=False``: a key the library
  always writes may be missing from someone else's file, and unknown keys are kept.
- Constructor arguments that take such a record accept the record or any ``dict`` of
  JSON-like values (``...Input`` aliases): the extension needs a real ``dict``.
- :class:`SimConfig` (the twin's nested configuration, validated by the Rust side) is
  one ``total=False`` TypedDict per group of knobs. ``Truth.extra`` is a :class:`TruthExtra`.
"""

from typing import Dict, List, Optional, TypedDict, Union

import numpy as np
import numpy.typing as npt

from stripecal._core import Camera

F64 = npt.NDArray[np.float64]
"""A float64 numpy array."""
I64 = npt.NDArray[np.int64]
"""An int64 numpy array."""
Gray = Union[npt.NDArray[np.uint8], npt.NDArray[np.uint16]]
"""A 2D gray image, uint8 or uint16."""

__all__ = [
    "AxzbSolution",
    "BenchView",
    "BoardScaleCheck",
    "BoardStripeBias",
    "CalibrationExtra",
    "CalibrationExtraInput",
    "CalibrationQuality",
    "CalibrationQualityInput",
    "CalibrationSummary",
    "CalibrationUncertainty",
    "CalibrationUncertaintyInput",
    "CalibrationView",
    "CameraCalibration",
    "CameraParamSigma",
    "CameraRecord",
    "CameraSigma",
    "CircleDetection",
    "DatasetView",
    "DroppedCircle",
    "F64",
    "Flatness",
    "Gray",
    "I64",
    "LaserBoardFigure",
    "LaserPlaneFit",
    "LeaveOneOut",
    "LeaveOneOutFold",
    "LeaveOneOutView",
    "PlaneRecord",
    "PlaneSigma",
    "PlyCloud",
    "PoseRecord",
    "PoseSigma",
    "ProfilerAdjustment",
    "ProfilerCalibrationAdjustment",
    "ProfilerCentreSpread",
    "ProfilerCounts",
    "ProfilerDiameterCheck",
    "ProfilerExtra",
    "ProfilerExtraInput",
    "ProfilerLeaveOneOut",
    "ProfilerLeaveOneOutView",
    "ProfilerMirrorTest",
    "ProfilerPose",
    "ProfilerQuality",
    "ProfilerRobot",
    "ProfilerStand",
    "ProfilerStart",
    "ProfilerSummary",
    "ProfilerTruth",
    "ProfilerTruthView",
    "ProfilerUncertainty",
    "ProfilerUncertaintyInput",
    "ProfilerView",
    "ProfilerViewCounts",
    "QualityCheck",
    "ResidualSigma",
    "RobotPoseAtFloor",
    "RobotPoseFloor",
    "RobotPoseNoise",
    "RobotPoseNoiseView",
    "ScanLinesWithoutPoint",
    "SimBench",
    "SimBenchScan",
    "SimBoard",
    "SimBow",
    "SimCamera",
    "SimConfig",
    "SimDh",
    "SimFloor",
    "SimImaging",
    "SimPlane",
    "SimPose",
    "SimPoseCfg",
    "SimPoses",
    "SimProfiler",
    "SimRobot",
    "SimScan",
    "SimVerify",
    "SimVerifyMpe",
    "SimVerifyUncertainty",
    "SkippedFrame",
    "SphereFitExtra",
    "SphereFitExtraInput",
    "SphereInput",
    "SphereSigma",
    "SphereTruth",
    "StripeExtraction",
    "StripeLeftOut",
    "TruthArtefactPlane",
    "TruthArtefactSphere",
    "TruthExtra",
    "TruthImage",
    "TruthPlate",
    "TwinDhRow",
    "TwinPlane",
    "TwinSphere",
    "TwinSummary",
    "TwinViewSummary",
    "VerifyScan",
    "ViewRender",
]


# --- io: dataset folders and point clouds ---------------------------------------------


class DatasetView(TypedDict):
    """One view of a dataset folder (``Dataset.views``): a row of views.csv."""

    line: int
    """Line number of the view in views.csv."""
    board_image: str
    """Path of the board image, joined with the dataset folder."""
    laser_image: Optional[str]
    """Path of the laser image, or None (single-image datasets)."""
    joints: Optional[F64]
    """Encoder readings (J,) in degrees, or None when the view gives a flange pose."""
    flange_pose: Optional[F64]
    """``T_base_hand`` (4, 4) in mm, or None when the view gives joint readings."""


class PlyCloud(TypedDict):
    """A PLY point cloud as read by ``read_ply``."""

    points: F64
    """Points (N, 3), mm."""
    properties: Dict[str, F64]
    """Other per-point properties by PLY name, each (N,) float64 (e.g. ``view``, ``u``,
    ``v``, ``intensity``, ``flags`` for clouds written by stripecal)."""


class SkippedFrame(TypedDict):
    """A scan frame left out because its image could not be used
    (``Cloud.skipped_frames`` after ``reconstruct_scan(..., on_bad_image="skip")``)."""

    frame: int
    """Index of the frame: its row of scan.csv after the header, from 0 (the ``view``
    property of the other frames' points)."""
    line: int
    """Its line in scan.csv (the header is line 1)."""
    path: str
    """The image file, joined with the scan folder."""
    reason: str
    """What is wrong: does not exist, cannot be read, cannot be decoded (truncated or
    corrupted), the wrong size, or another bit depth than the scan's other frames."""


# --- calib: calibration results -------------------------------------------------------


class QualityCheck(TypedDict):
    """One quality gate's verdict (``Calibration.quality["checks"]``,
    ``CalibrationQualityError.checks``)."""

    name: str
    """``pairing`` (robot poses against images), ``views`` (a view's residuals against
    the others'), ``determined`` (every estimated number has a meaningful one-sigma) or
    ``converged`` (the adjustment reached its tolerance)."""
    passed: bool
    """Whether the gate passed."""
    message: str
    """What was measured, against what limit, and what to do."""
    views: List[int]
    """The views (views.csv rows, 0-based) the check names as suspect (left out when the
    gate passed, the reason it failed otherwise)."""


class CalibrationQuality(TypedDict):
    """Quality figures of a calibration (``Calibration.quality``)."""

    target_rms_px: float
    """RMS target-point residual over the used views (circle centres or chessboard
    corners), px."""
    circle_rms_px: float
    """The same figure under calibration.json's contract name."""
    stripe_rms_px: float
    """RMS stripe-point distance from the predicted stripe line, px."""
    views_used: int
    """Number of views the calibration used."""
    accepted_poor: bool
    """True when a quality gate failed and the calibration was kept anyway
    (``accept_poor=True``, ``--accept-poor``)."""
    checks: List[QualityCheck]
    """Every quality gate's verdict (empty for files written before the gates)."""


class CalibrationQualityInput(TypedDict, total=False):
    """What ``Calibration(quality=...)`` accepts: any of the keys of
    ``CalibrationQuality`` (missing ones are 0, False or empty; unknown keys are an
    error)."""

    target_rms_px: float
    circle_rms_px: float
    stripe_rms_px: float
    views_used: int
    accepted_poor: bool
    checks: List[QualityCheck]


class CameraSigma(TypedDict, total=False):
    """One-sigma of the camera parameters (``uncertainty["camera"]``); None where not
    finite (unobservable)."""

    fu: Optional[float]
    """Focal length along u, px."""
    fv: Optional[float]
    """Focal length along v, px."""
    u0: Optional[float]
    """Principal point u, px."""
    v0: Optional[float]
    """Principal point v, px."""
    distortion: List[Optional[float]]
    """The five distortion coefficients ``k1, k2, p1, p2, k3`` (0 for those the model
    does not estimate)."""


class PlaneSigma(TypedDict, total=False):
    """One-sigma of the laser plane (``uncertainty["laser_plane"]``)."""

    normal: List[Optional[float]]
    """Of the unit normal's three components."""
    d_mm: Optional[float]
    """Of the plane's distance ``d``, mm."""


class PoseSigma(TypedDict, total=False):
    """One-sigma of a rigid transform (``uncertainty["hand_cam"]``,
    ``uncertainty["base_board"]``)."""

    rotation_vector: List[Optional[float]]
    """Of the rotation vector's three components, rad."""
    translation_mm: List[Optional[float]]
    """Of the translation's three components, mm."""


class CalibrationUncertainty(TypedDict, total=False):
    """One-sigma values of a calibration (``Calibration.uncertainty``), mirroring the
    estimated values' keys. A ``paper``-method calibration has only ``camera`` and
    ``laser_plane``."""

    camera: CameraSigma
    """The camera parameters."""
    laser_plane: PlaneSigma
    """The laser plane."""
    hand_cam: PoseSigma
    """``T_hand_cam`` (X); one-stage only."""
    base_board: PoseSigma
    """``T_base_board`` (Z); one-stage only."""


CalibrationUncertaintyInput = Union[CalibrationUncertainty, Dict[str, object]]
"""What ``Calibration(uncertainty=...)`` accepts: the record or any dict of JSON-like
values (stored as given)."""


class ProfilerQuality(TypedDict):
    """Quality figures of a line profiler's calibration (``ProfilerCalibration.quality``)."""

    profile_rms_mm: float
    """RMS distance of the sphere points used from the fitted sphere, mm."""
    views_used: int
    """Number of views the calibration used."""
    accepted_poor: bool
    """True when a quality gate failed and the calibration was kept anyway."""
    checks: List[QualityCheck]
    """Every quality gate's verdict."""


class SphereSigma(TypedDict, total=False):
    """One-sigma of a reference sphere (``ProfilerCalibration.uncertainty["sphere"]``)."""

    center_mm: List[Optional[float]]
    """Of the centre's three components (base frame), mm."""
    diameter_mm: Optional[float]
    """Of the diameter, mm (absent or None when it was declared, not estimated)."""


class ProfilerUncertainty(TypedDict, total=False):
    """One-sigma values of a line profiler's calibration
    (``ProfilerCalibration.uncertainty``), mirroring the estimated values' keys."""

    hand_cam: PoseSigma
    """``T_hand_sensor``."""
    sphere: SphereSigma
    """The reference sphere."""


ProfilerUncertaintyInput = Union[ProfilerUncertainty, Dict[str, object]]
"""What ``ProfilerCalibration(uncertainty=...)`` accepts: the record or any dict of
JSON-like values (stored as given)."""


class ResidualSigma(TypedDict):
    """Residual standard deviations estimated by the adjustment, px."""

    circle: float
    """Of a target point's residual (per coordinate)."""
    stripe: float
    """Of a stripe point's distance from its predicted line."""


class _CalibrationSummaryKeys(TypedDict):
    method: str
    """``"one-stage"`` or ``"paper"``."""
    centre_model: str
    """The circle-centre model (e.g. ``"conic-exact"``)."""
    stripe_rms_mm: Optional[float]
    """RMS of the stripe points' distance from the laser plane, mm (None: no stripe
    points)."""
    residual_sigma_px: ResidualSigma
    """Residual standard deviations estimated by the adjustment."""
    stripe_off_plane: int
    """Stripe points rejected as off the board plane, all views."""


class CalibrationSummary(_CalibrationSummaryKeys, total=False):
    """How a calibration was made (``Calibration.summary``; calibration.json's
    ``method``, ``centre_model``, ``base_board_orientation``, ``stripe_rms_mm``,
    ``residual_sigma_px``, ``stripe_off_plane``)."""

    base_board_orientation: str
    """``"first view"`` when no view's image fixed the board frame's orientation and
    the first view's labelling did (docs/conventions.md); absent otherwise."""


class StripeLeftOut(TypedDict):
    """Stripe points the extraction found but left out as biased."""

    at_edge: int
    """A reflectance edge of the board image in their support."""
    uneven_background: int
    """An uneven background in the stripe image across their support."""
    oblique: int
    """The stripe crosses the scan line at a shallow angle there."""


class ScanLinesWithoutPoint(TypedDict):
    """Scan lines of a laser image that gave no stripe point, by reason."""

    no_peak: int
    multiple_peaks: int
    """Two or more comparable peaks that the line's continuity did not decide."""
    saturated: int
    """A saturated plateau longer than ``max_saturated_px``."""
    shape: int
    """A width outside the accepted range, or a peak too weak."""
    border: int
    isolated: int
    """Not part of a chain of neighbouring points."""
    reflection_only: int
    """The only peak continues a reflection (a line that lost to a heavier one where
    both were seen)."""


class StripeExtraction(TypedDict):
    """What the stripe extraction of one view found and left out
    (``CalibrationView["stripe_extraction"]``)."""

    scan_lines: int
    """Scan lines searched."""
    found: int
    """Stripe points found."""
    left_out: StripeLeftOut
    """Of them, left out as biased."""
    saturated: int
    """Of the points kept, those whose profile holds a saturated pixel."""
    saturated_share: Optional[float]
    """``saturated`` over the points kept (above 0.5 the CLI advises lowering the
    exposure or the laser power)."""
    width_px: Optional[float]
    """The line's width across, px (the extractor's survey)."""
    along_line: int
    """Scan lines averaged along the line before the centres (1: none; 5 for a
    saturated or speckled line)."""
    scan_lines_without_point: ScanLinesWithoutPoint
    """Scan lines that gave no point, by reason."""
    reflections_left_out: int
    """Scan lines that gave a point from the peak continuing the line while holding
    another comparable peak (a reflection) that was left out."""
    ambiguous_scan_lines: int
    """Scan lines with two comparable peaks that the line's continuity did not decide
    between: both were kept, and the board plane's consensus chose."""


class _CalibrationViewBase(TypedDict):
    view: int
    """Index of the view in the dataset (views.csv order)."""
    used: bool
    """Whether the calibration used the view."""
    circles: int
    """Target points detected in the view (circle centres or chessboard corners)."""
    stripe_points: int
    """Stripe points on the board the adjustment used."""
    stripe_off_plane: int
    """Stripe points rejected as off the board plane (beyond a depth step where the
    sheet ends, on something behind)."""
    circle_rms_px: Optional[float]
    """RMS target residual of the view, px (None when not adjusted or not finite)."""
    stripe_rms_px: Optional[float]
    """RMS stripe residual of the view, px (None when not adjusted or not finite)."""
    outlier: Optional[bool]
    """Whether the adjustment flagged the view as an outlier (None when not
    adjusted)."""
    note: Optional[str]
    """Why the view was left out, if it was."""


class CalibrationView(_CalibrationViewBase, total=False):
    """Per-view figures of a calibration (``Calibration.views``)."""

    stripe_extraction: StripeExtraction
    """What the stripe extraction found and left out (views with a laser image; absent
    from files written before it existed)."""


class _LeaveOneOutViewBase(TypedDict):

    view: int
    """Index of the view in the dataset (views.csv order)."""
    points: int
    """Target points compared."""
    board_rms_px: float
    """RMS length of (predicted - detected) target point, px."""
    board_rms_mm: float
    """RMS distance on the predicted board plane between each detected point's viewing
    ray and the point's predicted position, mm."""
    stripe_points: int
    """Stripe points compared (0 without laser image or laser plane)."""
    stripe_rms_mm: Optional[float]
    """RMS distance of its stripe points (triangulated with the laser plane) from its
    predicted board plane, mm (None without stripe points)."""
    disagrees: bool
    """Whether the view disagrees with the others: ``board_rms_px`` beyond 3 times the
    median over views."""


class CameraRecord(TypedDict):
    """A camera as calibration.json writes it (its ``camera`` key)."""

    width: int
    height: int
    fu: float
    fv: float
    u0: float
    v0: float
    distortion_model: str
    distortion: List[float]
    """``[k1, k2, p1, p2, k3]``."""


class PlaneRecord(TypedDict):
    """A laser plane ``normal . p = d_mm`` in the camera frame, as calibration.json
    writes it."""

    normal: List[float]
    d_mm: float


class PoseRecord(TypedDict):
    """A rigid transform as calibration.json writes it."""

    rotation_vector: List[float]
    """Axis times angle, rad."""
    translation_mm: List[float]


class LeaveOneOutFold(TypedDict):
    """What the calibration without a view predicts for that view: enough to score any
    stripe points of it (``Calibration.held_out_laser_board``)."""

    camera: CameraRecord
    laser_plane: PlaneRecord
    cam_board: PoseRecord
    """The view's board pose in the camera frame, ``T_cam_board``, from its robot pose
    (on the bench: from its own target points)."""


class LeaveOneOutView(_LeaveOneOutViewBase, total=False):
    """One view's leave-one-view-out figures: its observations predicted by the
    calibration solved without it, from its robot pose alone."""

    fold: LeaveOneOutFold
    """The calibration without the view, as far as scoring its stripe points needs
    (with a laser plane; absent from files written before it existed)."""


class LaserBoardFigure(TypedDict):
    """The held-out laser->board distance (DECISIONS 8): each stripe point of each view
    triangulated with the laser plane of the calibration without that view, its distance
    from the board plane that calibration predicts for the view; over all points."""

    median_mm: float
    p95_mm: float
    """The 95th percentile, mm."""
    points: int
    """Points scored."""


class _LeaveOneOutBase(TypedDict):
    views: List[LeaveOneOutView]
    """Per view."""
    median_board_rms_px: float
    """Median over views of ``board_rms_px``."""
    median_board_rms_mm: float
    """Median over views of ``board_rms_mm``."""
    median_stripe_rms_mm: Optional[float]
    """Median over views with stripe points of ``stripe_rms_mm``."""


class LeaveOneOut(_LeaveOneOutBase, total=False):
    """The leave-one-view-out figures of a calibration (``Calibration.leave_one_out``):
    the out-of-sample figure to quote for a real rig."""

    laser_board: LaserBoardFigure
    """The held-out laser->board distance of the calibration's own stripe points (with
    a laser plane; absent from files written before it existed)."""


class BoardScaleCheck(TypedDict):
    """The board's printed scale as the robot's translations imply it
    (``Calibration.board_scale``)."""

    scale: float
    """The scale the robot implies: the printed board is ``scale`` times rig.json's."""
    sigma: float
    """Its one-sigma (NaN when the poses do not determine it)."""
    declared_mm: float
    """rig.json's pitch (circle grids) or square (chessboards), mm."""
    implied_mm: float
    """``scale * declared_mm``."""
    estimated: bool
    """Whether the calibration freed the scale (``estimate_board_scale``)."""
    disagrees: bool
    """Whether rig.json disagrees: ``|scale - 1|`` beyond 3 sigma and the tolerance."""
    tolerance: float
    """The tolerance on ``|scale - 1|``."""


class RobotPoseAtFloor(TypedDict):
    """Which robot-pose sigmas sit at their floor (``RobotPoseNoise.at_floor``)."""

    translation: bool
    """The translation's sigma is its floor (the estimate is below it)."""
    rotation: bool
    """The rotation's sigma is its floor."""
    image: bool
    """The image part's factor is at its floor (the images are as good as their
    residuals say; False in files written before it existed)."""


class RobotPoseFloor(TypedDict):
    """The floors of the robot-pose sigmas (``RobotPoseNoise.floor``): rig.json's
    ``robot.repeatability_mm`` and ``robot.encoder_sigma_deg`` (at the flange) when given,
    never below the adjustment's resolution floor."""

    translation_mm: Optional[float]
    """Of a translation component, mm."""
    rotation_deg: Optional[float]
    """Of a rotation component, degrees."""


class RobotPoseNoiseView(TypedDict):
    """One view's robot-pose correction (``RobotPoseNoise.views``)."""

    view: int
    """Index of the view in the dataset (views.csv order)."""
    translation_mm: Optional[float]
    """Length of the correction's translation (flange frame), mm."""
    rotation_deg: Optional[float]
    """Angle of the correction's rotation, degrees."""
    test: Optional[float]
    """The view's correction against its own predicted covariance, as a standard normal
    deviate: about N(0, 1) when the view agrees with the noise model, above about 4 when
    it disagrees (None when not computable)."""


class RobotPoseNoise(TypedDict):
    """The robot-pose noise the one-stage adjustment estimated with a correction of every
    view's flange pose (``Calibration.robot_pose_noise``)."""

    translation_mm: Optional[float]
    """One-sigma of a flange translation component, mm."""
    rotation_deg: Optional[float]
    """One-sigma of a flange rotation component, degrees."""
    image_factor: Optional[float]
    """The part of each view's pose error its own image makes (detector biases, a board
    not quite flat, a lens the model does not quite fit), in units of the image's own
    uncertainty of the view's pose; None when not modelled (files written before it
    existed)."""
    kinematic_mm: Optional[float]
    """With joint readings and rig.json's DH table: the DH length error (one-sigma, mm)
    the pose noise is consistent with, whose effect on X and Z the covariance carries;
    None otherwise."""
    kinematic_deg: Optional[float]
    """The same for the DH angles, degrees."""
    at_floor: RobotPoseAtFloor
    """Which of the components sits at its floor."""
    floor: RobotPoseFloor
    """The floors."""
    views: List[RobotPoseNoiseView]
    """Per view used."""
    left_out: List[RobotPoseNoiseView]
    """Views left out because their test exceeded 4 (their figures from the adjustment
    that found them; empty in files written before it existed)."""


class DhCorrection(TypedDict):
    """One DH correction the robot calibration estimated."""

    name: str
    """``robot.joints[i].theta0_deg`` style (0-based row; the covariance's name)."""
    correction: Optional[float]
    """The refined value minus rig.json's nominal one, degrees or mm."""
    sigma: Optional[float]
    """Its one-sigma."""


class DhFixed(TypedDict):
    """A candidate DH correction held at rig.json's value, and why."""

    name: str
    reason: str
    """Absorbed by the hand-eye X or the robot-world Z, a combination of estimated
    corrections (named), or not shown by the data (``auto``)."""


class RobotCalibration(TypedDict):
    """What ``--robot`` / ``calibrate(robot=...)`` did (``Calibration.robot_calibration``);
    the refined DH rows are ``Calibration.robot``."""

    mode: str
    """``offsets``, ``full`` or ``auto``."""
    estimated: List[DhCorrection]
    fixed: List[DhFixed]


class BoardStripeBias(TypedDict, total=False):
    """calibration.json's ``board_stripe_bias``: whether the stripe's sub-pixel bias on
    the board was corrected, and what the correction did (its ``emitter_response``, read
    by the measurement, is not typed here)."""

    applied: bool
    """Whether the correction was applied (absent from files written before it
    existed: they hold this record only when it was)."""
    reason: str
    """Why not, when not applied (a mostly saturated line, a line smoothed for
    speckle, too few points, the sheet undetermined)."""
    sheet_sigma_mm: float
    psf_sigma_px: float
    points_corrected: int
    points_left_out: int
    points_saturated: int
    mean_px: float
    rms_px: float
    neglected_share: float
    emitter_range_mm: float


class CalibrationExtra(TypedDict, total=False):
    """The other top-level keys of calibration.json (``Calibration.extra``). The
    library writes all but ``base_board_orientation`` and ``warnings`` (only when there
    are some); a file written elsewhere may lack any of them or hold others."""

    method: str
    """``"one-stage"`` or ``"paper"``."""
    centre_model: str
    """The circle-centre model (e.g. ``"conic-exact"``)."""
    base_board_orientation: str
    """``"first view"`` when no view's image fixed the board frame's orientation and
    the first view's labelling did (docs/conventions.md)."""
    stripe_rms_mm: float
    """RMS of the stripe points' distance from the laser plane, mm."""
    residual_sigma_px: ResidualSigma
    """Residual standard deviations estimated by the adjustment."""
    stripe_off_plane: int
    """Stripe points rejected as off the board plane, all views."""
    views: List[CalibrationView]
    """Per-view figures (also ``Calibration.views``)."""
    warnings: List[str]
    """Warnings of the calibration run (weak geometry, trimmed points, views left
    out...)."""
    board_scale: BoardScaleCheck
    """The board's scale against the robot."""
    leave_one_out: LeaveOneOut
    """The leave-one-view-out figures."""
    robot_pose_noise: RobotPoseNoise
    """The robot-pose noise estimated by the one-stage adjustment."""
    robot_calibration: RobotCalibration
    """The robot's DH corrections (``--robot``)."""
    board_stripe_bias: BoardStripeBias
    """The correction of the stripe's bias on the board."""
    held_blocks: List[str]
    """The blocks held at the values of the calibration it started from (their
    uncertainty is that file's; the others' is conditional on them)."""
    stripe_channel: str
    """The signal the stripes were found in, ``"gray"``, ``"red"``, ``"green"`` or
    ``"blue"`` (written when rig.json's ``stripe.channel`` is not gray; docs/colour.md)."""
    stripe_channel_scores: Dict[str, float]
    """``stripe.channel: auto``: each signal's score (summed stripe peak-to-noise ratio
    over the laser images looked at) by name."""


CalibrationExtraInput = Union[CalibrationExtra, Dict[str, object]]
"""What ``Calibration(extra=...)`` accepts: the record or any dict of JSON-like values."""


class ProfilerCalibrationAdjustment(TypedDict):
    """The adjustment's figures of a profiler calibration
    (``ProfilerCalibration.adjustment``, calibration.json's ``adjustment``)."""

    sigma_mm: Optional[float]
    """A-posteriori sigma of a point's distance from the sphere, mm."""
    points_used: int
    """The sphere points the adjustment used."""
    iterations: int
    view_variance_factor: Optional[float]
    """The view-clustered variance factor the sigmas carry (>= 1)."""


class ProfilerView(TypedDict):
    """One view of a profiler calibration, used or not (``ProfilerCalibration.views``)."""

    view: int
    line: int
    """The line of views.csv."""
    profile: str
    """The profile file."""
    used: bool
    points: int
    gaps: int
    arc_points: int
    sphere_points: int
    rejected: int
    rms_mm: Optional[float]
    """RMS distance from the sphere, mm (None: not used)."""
    side: Optional[float]
    """The side of the laser plane the sphere's centre was on (+1 / -1)."""
    centre_in_sensor_mm: Optional[List[Optional[float]]]
    """The sphere's centre in the sensor frame, mm."""
    note: Optional[str]
    """Why the view was not used."""


class ProfilerCentreSpread(TypedDict):
    """The sphere centres' spread in the sensor frame, mm."""

    x: Optional[float]
    y: Optional[float]
    z: Optional[float]
    across_plane: Optional[float]


class ProfilerMirrorTest(TypedDict):
    """The fit against its mirror image through the laser plane
    (``ProfilerCalibration.mirror``)."""

    ssr_chosen_mm2: Optional[float]
    ssr_mirror_mm2: Optional[float]
    delta_chi2: Optional[float]
    passed: bool
    centre_spread_mm: ProfilerCentreSpread


class ProfilerDiameterCheck(TypedDict):
    """The declared sphere diameter against the profiles' (``ProfilerCalibration.diameter_check``)."""

    declared_mm: Optional[float]
    estimate_mm: Optional[float]
    sigma_mm: Optional[float]
    disagrees: bool


class ProfilerLeaveOneOutView(TypedDict):
    """One view held out (``ProfilerLeaveOneOut["views"]``)."""

    view: int
    points: int
    rms_mm: Optional[float]
    """Held-out RMS distance from the sphere the other views predict, mm."""
    disagrees: bool


class ProfilerLeaveOneOut(TypedDict):
    """The leave-one-view-out figures of a profiler calibration
    (``ProfilerCalibration.leave_one_out``)."""

    median_rms_mm: Optional[float]
    views: List[ProfilerLeaveOneOutView]


class ProfilerExtra(TypedDict, total=False):
    """The other top-level keys of a profiler's calibration.json
    (``ProfilerCalibration.extra``); each also has its typed getter."""

    robot_calibration: RobotCalibration
    sphere_diameter_estimated: bool
    adjustment: ProfilerCalibrationAdjustment
    views: List[ProfilerView]
    mirror: ProfilerMirrorTest
    diameter_check: ProfilerDiameterCheck
    leave_one_out: ProfilerLeaveOneOut
    warnings: List[str]


ProfilerExtraInput = Union[ProfilerExtra, Dict[str, object]]
"""What ``ProfilerCalibration(extra=...)`` accepts: the record or any dict of JSON-like
values (the other top-level keys of calibration.json: the records it holds become the
calibration's, the rest is written back as given)."""


CameraParamSigma = TypedDict(
    "CameraParamSigma",
    {"fu": float, "fv": float, "u0": float, "v0": float, "k1": float, "k2": float,
     "p1": float, "p2": float, "k3": float},
)
"""One-sigma of each camera parameter by name (the names of ``CAMERA_PARAM_NAMES``:
``fu``, ``fv``, ``u0``, ``v0`` in px, the distortion coefficients ``k1, k2, p1, p2, k3``;
NaN where unobservable, 0 where not estimated)."""


class CameraCalibration(TypedDict):
    """The camera calibrated alone (``calibrate_camera``)."""

    camera: Camera
    """The calibrated camera."""
    cam_board: F64
    """Board poses ``T_cam_board`` (K, 4, 4) of the K views used, mm."""
    views_used: List[int]
    """Indices in the input ``views`` of the views used."""
    rms_px: float
    """RMS target residual over the views used, px."""
    per_view_rms_px: List[float]
    """RMS target residual of each view used, px."""
    camera_sigma: CameraParamSigma
    """One-sigma of the camera parameters by name."""
    initial_intrinsics: List[float]
    """Zhang's closed-form start ``[fu, fv, u0, v0]``, px."""
    unobservable: List[str]
    """Names of the parameters the views do not determine."""
    warnings: List[str]
    """Warnings (weak geometry, views left out...)."""


class LaserPlaneFit(TypedDict):
    """The laser plane fitted to stripe points on the board (``fit_laser_plane``),
    camera frame, ``n . p = d``."""

    normal: F64
    """Unit normal (3,)."""
    d_mm: float
    """Distance of the plane from the camera centre, mm (> 0)."""
    rms_mm: float
    """RMS distance of the points from the plane, mm."""
    per_view_rms_mm: List[Optional[float]]
    """RMS per view, mm (None for views without points)."""
    n_points: int
    """Points used."""
    n_outliers: int
    """Points rejected as outliers."""
    normal_sigma: F64
    """One-sigma of the normal's components (3,)."""
    d_sigma_mm: float
    """One-sigma of ``d``, mm."""
    max_line_angle_deg: float
    """Largest angle between the views' stripe lines, degrees (small: a weak fit)."""
    span_across_mm: float
    """Extent of the points across the stripe lines, mm."""
    warnings: List[str]
    """Warnings (weak geometry)."""


class Flatness(TypedDict):
    """The flatness figure of one board view (``board_flatness``, docs/flatness.md):
    the sag of the best-fitting cylinder across the bend."""

    sag_mm: float
    """Sag at the middle across the width ``W``, mm (positive: towards the camera)."""
    sigma_mm: float
    """One-sigma of ``sag_mm``, mm."""
    axis_deg: float
    """The cylinder's axis in the board plane, degrees from board x, in (-90, 90]."""
    width_mm: float
    """``W``: the extent of the view's points across the bend, mm."""
    sag2_mm: float
    """The same figure along the axis, mm (near 0 for a cylinder)."""
    sigma2_mm: float
    """One-sigma of ``sag2_mm``, mm."""
    rms_px: float
    """RMS point residual of the bent fit, px."""
    rms_flat_px: float
    """RMS point residual of a flat board, px."""
    points: int
    """Points used."""
    cam_board: F64
    """The refined ``T_cam_board`` (4, 4)."""


class BenchView(TypedDict):
    """A board pose of the twin's bench mode (``Twin.bench_views``)."""

    cam_board: F64
    """True ``T_cam_board`` (4, 4) (a bent sheet's edges across the bend lie in z = 0)."""
    standoff_mm: float
    """Depth of the grid's centre, mm."""
    tilt_deg: float
    """Angle between the optical axis and the board normal, degrees."""
    partial: bool
    """The board is partly out of the image."""
    sag_mm: float
    """True sag of a bent board, mm (0: flat)."""
    bow_axis_deg: Optional[float]
    """The bend's axis, degrees from board x (None: flat)."""
    floor_normal: Optional[F64]
    """The floor's normal (3,) in the camera frame (``bench.floor``), or None."""
    floor_d_mm: Optional[float]
    """The floor plane's ``d`` (``n . p = d``), or None."""


class AxzbSolution(TypedDict):
    """The solution of ``A_i X = Z B_i`` (``solve_axzb_full``) with its conditioning."""

    X: F64
    """``X`` (4, 4): the hand-eye transform ``T_hand_cam``."""
    Z: F64
    """``Z`` (4, 4): the robot-world transform ``T_base_board``."""
    rotation_residual_rad: float
    """RMS rotation residual over the pairs, rad."""
    translation_residual: float
    """RMS translation residual over the pairs, mm."""
    axis_spread_deg: float
    """Spread of the rotation axes of the motions, degrees (small: ill-conditioned)."""
    max_rotation_deg: float
    """Largest rotation among the motions, degrees."""
    min_rotation_deg: float
    """Smallest rotation among the motions, degrees."""
    rotation_condition: float
    """Condition number of the rotation part's linear system."""
    refined: bool
    """Whether the nonlinear refinement ran (``refine=True``) and was kept."""
    warnings: List[str]
    """Warnings (weak geometry)."""


# --- pose planning -------------------------------------------------------------------


class PlannedPose(TypedDict):
    """One robot pose of a plan (``plan_poses``)."""

    pose: int
    """Index in the joints given (0-based)."""
    joints_deg: List[float]
    """The joint values, degrees."""
    usable: bool
    """Whether the pose enters the prediction."""
    reason: Optional[str]
    """Why it does not (None when usable)."""
    points: int
    """Target points imaged inside the margin."""
    stripe_points: int
    """Predicted stripe points on the board's plate."""
    standoff_mm: Optional[float]
    """Where the optical axis meets the board plane, mm from the camera (None: not in
    front of the camera)."""
    tilt_deg: Optional[float]
    """Angle between the optical axis and the board's normal, degrees."""


class SigmaEntry(TypedDict):
    """A predicted one-sigma by name."""

    name: str
    """calibration.json's name (``camera.fu``, ``laser_plane.normal[0]``,
    ``hand_cam.rotation_vector[2]``...) or the adjustment's state name."""
    sigma: float
    """One-sigma in the number's unit (px, mm, rad)."""


class PointSigma(TypedDict):
    """The predicted uncertainty of a point triangulated on the laser plane."""

    standoff_mm: float
    """The point's depth (camera z), mm."""
    pixel: List[float]
    """Its pixel ``[u, v]``: nearest the optical axis on the stripe at that depth."""
    camera_mm: List[float]
    """The point in the camera frame ``[x, y, z]``, mm."""
    sigma_camera_mm: List[float]
    """One-sigma of x, y, z in the camera frame, mm."""
    sigma_camera_norm_mm: float
    """One-sigma of the position (root of the covariance's trace), mm."""
    base_pose: Optional[int]
    """The pose (usable, median stand-off) at which the point is put in the base frame
    (None: X and Z both held)."""
    base_mm: Optional[List[float]]
    """The point in the base frame at that pose, mm."""
    sigma_base_mm: Optional[List[float]]
    """One-sigma of its x, y, z in the base frame, mm."""
    sigma_base_norm_mm: Optional[float]
    """One-sigma of the base-frame position, mm."""
    board_mm: Optional[List[float]]
    """The same point in the board's frame (``Z^-1`` of the base point), mm."""
    sigma_board_mm: Optional[List[float]]
    """One-sigma of its x, y, z in the board's frame: relative to the world the board is
    fixed in (what a measurement of a part on the table carries), mm."""
    sigma_board_norm_mm: Optional[float]
    """One-sigma of the board-frame position, mm."""


class PosePlan(TypedDict):
    """The predicted uncertainty of a calibration from a list of robot poses, before any
    image is taken (``plan_poses``)."""

    poses: List[PlannedPose]
    """Every pose given, usable or not."""
    usable: int
    """Usable poses."""
    sigma_px: List[float]
    """The detection noise assumed ``[circle, stripe]``, px."""
    points: int
    """Target points of the usable poses."""
    stripe_points: int
    """Stripe points of the usable poses."""
    parameters: List[SigmaEntry]
    """One-sigma of every estimated number, calibration.json's names."""
    covariance: List[List[float]]
    """Their covariance, rows and columns in ``parameters`` order."""
    state: List[SigmaEntry]
    """One-sigma of every entry of the adjustment's state vector (its own names)."""
    point: Optional[PointSigma]
    """The point at the stand-off (None without a laser plane)."""
    warnings: List[str]
    """Warnings."""
    robot_held: List[DhFixed]
    """With ``robot=``: the DH corrections the identifiability rule holds, and why."""
    pose_noise_mm_deg: Optional[List[float]]
    """The robot-pose noise planned with (one-sigma per flange component: translation mm,
    rotation deg): ``pose_noise=``, else the nominal calibration's estimate, else rig.json's
    figures; None when the robot is planned exact (none of them)."""


# --- vision: target detection ---------------------------------------------------------


class DroppedCircle(TypedDict):
    """An indexed circle left out of a detection."""

    row: int
    """Board row of the circle."""
    col: int
    """Board column of the circle."""
    u: float
    """Its measured centre u, px."""
    v: float
    """Its measured centre v, px."""
    reason: str
    """Why it was left out (e.g. crossed by the stripe)."""


class CircleDetection(TypedDict):
    """A circle-grid detection with its diagnostics (``detect_circles_full``); N
    indexed circles."""

    indices: I64
    """Board indices (N, 2): ``(row, col)``."""
    centres: F64
    """Measured centres (N, 2): ``(u, v)``, px."""
    quality_px: F64
    """Per-circle fit residual (N,), px."""
    area_px: F64
    """Blob area (N,), px^2."""
    axes_px: F64
    """Ellipse semi-axes (N, 2), px."""
    angle_rad: F64
    """Ellipse orientation (N,), rad (major axis from +u towards +v)."""
    stripe_crossed: npt.NDArray[np.bool_]
    """Whether a stripe crosses the circle (N,)."""
    dropped: List[DroppedCircle]
    """Indexed circles left out."""
    blobs: int
    """Candidate blobs found."""
    nodes_grown: int
    """Grid nodes reached by growing from the seed."""
    nodes_inconsistent: int
    """Grid nodes refused as inconsistent with their neighbours."""
    homography_rms_px: float
    """RMS residual of a homography through the centres, px."""
    homography_max_px: float
    """Largest residual of that homography, px."""
    method: str
    """The centre method used (``"gravity"``, ``"conic"``...)."""


# --- sim: the digital twin ------------------------------------------------------------

# The twin's configuration, one TypedDict per group of knobs (the Rust twin's config
# structs; tests/test_sim.py checks their keys against a full configuration). All are
# total=False: overrides name only the knobs they change.


class SimCamera(TypedDict, total=False):
    """The twin's true camera (``SimConfig["camera"]``)."""

    width: int
    height: int
    fu: float
    fv: float
    u0: float
    v0: float
    distortion_model: str
    distortion: List[float]


class SimPlane(TypedDict, total=False):
    """The true laser plane ``n . p = d`` in the camera frame."""

    normal: List[float]
    d_mm: float


class SimPoseCfg(TypedDict, total=False):
    """A pose: rotation vector (rad) and translation (mm)."""

    rotation_vector: List[float]
    translation_mm: List[float]


class SimDh(TypedDict, total=False):
    """One DH row of the nominal robot (``beta_deg`` for a parallel joint)."""

    theta0_deg: float
    alpha_deg: float
    a_mm: float
    d_mm: float
    beta_deg: float


class SimRobot(TypedDict, total=False):
    """The nominal robot (rig.json's)."""

    name: str
    joints: List[SimDh]


class SimBoard(TypedDict, total=False):
    """The calibration target."""

    kind: str
    rows: int
    cols: int
    pitch_mm: float
    circle_diameter_mm: float
    marker_diameter_mm: float
    markers: List[List[int]]
    dark_circles: bool
    square_mm: Optional[float]
    plate_margin_mm: float
    plate_thickness_mm: float


class SimPoses(TypedDict, total=False):
    """How the calibration views are planned."""

    count: int
    home_q_deg: List[float]
    standoff_mm: List[float]
    max_tilt_deg: float
    max_roll_deg: float
    max_joint_delta_deg: float
    margin_px: float
    max_laser_incidence_deg: float
    explicit_q_deg: Optional[List[List[float]]]
    stripe_beside_pattern: bool
    reading_noise_deg: float
    spread: str


class SimImaging(TypedDict, total=False):
    """The renderer's optics, lighting and noise."""

    bit_depth: int
    supersample: int
    ambient: float
    laser_ambient: float
    single_image: bool
    single_image_ambient: float
    plate_reflectance: float
    circle_reflectance: float
    table_reflectance: float
    sphere_reflectance: float
    vignetting: float
    psf_sigma_px: float
    noise_gray: float
    full_well_e: float
    laser_peak: float
    laser_sigma_mm: float
    laser_emitter_mm: Optional[List[float]]
    speckle_contrast: float
    speckle_grain_px: float
    reflection_ratio: float
    reflection_offset_px: List[float]
    colour: bool
    laser_colour: str
    ambient_rgb: List[float]
    plate_rgb: Optional[List[float]]
    ink_rgb: Optional[List[float]]


class SimScan(TypedDict, total=False):
    """The sphere scan (and the table beside it)."""

    enabled: bool
    sphere_diameter_mm: float
    sphere_offset_mm: List[float]
    step_mm: float
    margin_mm: float
    top_depth_mm: float
    max_frames: int
    table: bool
    table_offset_mm: List[float]


class SimVerifyUncertainty(TypedDict, total=False):
    """The certificate's expanded uncertainties (k = 2), mm."""

    diameter: float
    form: float
    length: float
    flatness: float


class SimVerifyMpe(TypedDict, total=False):
    """The maximum permissible errors, mm."""

    probing_form: float
    probing_size: float
    sphere_spacing: float
    flatness: float


class SimVerify(TypedDict, total=False):
    """The verification artefacts (ball bar, plate) and their certificate."""

    enabled: bool
    bar_length_mm: float
    sphere_diameter_mm: float
    bar_positions: int
    plate_positions: int
    plate_size_mm: List[float]
    plate_inset_mm: float
    plate_reflectance: float
    step_mm: float
    margin_mm: float
    certificate_exact: bool
    uncertainty_k2_mm: SimVerifyUncertainty
    mpe_mm: SimVerifyMpe


class SimBow(TypedDict, total=False):
    """A bowed board in some bench views."""

    views: List[int]
    sag_mm: float
    axis_deg: float


class SimFloor(TypedDict, total=False):
    """The bench's floor in the images."""

    enabled: bool
    reflectance: float
    camera_pitch_deg: float


class SimBenchScan(TypedDict, total=False):
    """The bench mode's sphere scan."""

    enabled: bool
    sphere_diameter_mm: float
    center_depth_mm: Optional[float]
    step_mm: float
    margin_mm: float
    max_frames: int


class SimBench(TypedDict, total=False):
    """The bench mode: a fixed sensor, the board placed by hand."""

    enabled: bool
    views: int
    standoff_mm: Optional[List[float]]
    max_tilt_deg: float
    partial_views: int
    min_imaged: float
    partial_keep_markers: bool
    margin_px: float
    min_stripe_mm: float
    bow: SimBow
    floor: SimFloor
    scan: SimBenchScan


class SimProfiler(TypedDict, total=False):
    """The profiler mode: a line profiler measuring a reference sphere."""

    enabled: bool
    line_length_mm: float
    spacing_mm: float
    z_min_mm: float
    z_max_mm: float
    noise_z_mm: float
    gap_fraction: float
    spike_fraction: float
    spike_min_mm: float
    spike_max_mm: float
    invalid_z: Optional[float]
    intensity: bool
    sphere_diameter_mm: float
    sphere_center_mm: List[float]
    stand_height_mm: float
    stand_diameter_mm: float
    diameter_declared: bool
    hand_sensor: SimPoseCfg
    views: int
    standoff_min_mm: float
    standoff_max_mm: float
    place_max_mm: float
    offset_min_frac: float
    offset_max_frac: float
    tilt_min_deg: float
    tilt_max_deg: float
    spin_max_deg: float
    degenerate: str
    near_degenerate_mm: float
    max_joint_delta_deg: float
    poses: str
    pose_columns: str
    scan_frames: int
    scan_step_mm: float


class SimConfig(TypedDict, total=False):
    """A twin configuration (see :mod:`stripecal.sim`): the groups of knobs the Rust
    twin validates; a full one from :func:`stripecal.sim.preset`, overrides naming only
    what they change."""

    preset: str
    seed: int
    camera: SimCamera
    laser_plane: SimPlane
    hand_cam: SimPoseCfg
    base_board: Optional[SimPoseCfg]
    robot: SimRobot
    dh_errors: List[List[float]]
    robot_error: SimDh
    board: SimBoard
    poses: SimPoses
    imaging: SimImaging
    scan: SimScan
    working_range_mm: List[float]
    stripe_direction: str
    stripe_channel: Optional[str]
    pose_columns: Optional[str]
    verify: SimVerify
    bench: SimBench
    profiler: SimProfiler


class SimPose(TypedDict):
    """A calibration pose of the twin (``Twin.calibration_poses``)."""

    q_deg: F64
    """Encoder readings (J,), degrees."""
    standoff_mm: float
    """Stand-off along the optical axis to the board plane, mm."""
    tilt_deg: float
    """Angle between the optical axis and the board normal, degrees."""
    stripe_chord_mm: float
    """Length of the stripe on the board, mm."""


class TwinViewSummary(SimPose):
    """A calibration view written by ``Twin.write``: its pose and what it shows."""

    circles_visible: int
    """Imaged target points (circles or chessboard corners, whatever the kind)."""
    stripe_points_on_board: int
    """Stripe points on the board (one per scan line)."""


class TwinSphere(TypedDict):
    """The reference ball of a twin's scan, base frame."""

    center_mm: List[float]
    """Centre ``[x, y, z]``, mm."""
    diameter_mm: float
    """Diameter, mm."""


class TwinPlane(TypedDict):
    """A plane ``normal . p = d_mm``, base frame."""

    normal: List[float]
    """Unit normal ``[x, y, z]`` (towards the sensor)."""
    d_mm: float
    """Offset, mm."""


class TruthPlate(TypedDict):
    """The twin's board plate (truth.json's ``plate``), base frame."""

    normal: List[float]
    """Unit normal ``[x, y, z]`` (towards the sensor)."""
    d_mm: float
    """Offset, mm."""
    extent_mm: List[float]
    """The plate's extent in board coordinates ``[x0, x1, y0, y1]``, mm."""


class TruthArtefactSphere(TypedDict):
    """One sphere of a verification artefact (truth.json's ``spheres``)."""

    name: str
    """``"A"`` or ``"B"``."""
    center_mm: List[float]
    """Centre ``[x, y, z]``, base frame, mm."""
    diameter_mm: float
    """Diameter, mm."""


class TruthArtefactPlane(TypedDict):
    """The plane of a verification artefact (truth.json's ``plane``), base frame."""

    normal: List[float]
    """Unit normal ``[x, y, z]``."""
    d_mm: float
    """Offset, mm."""
    flatness_mm: float
    """Its true flatness (0), mm."""


class TruthImage(TypedDict, total=False):
    """One image's truth (truth.json's ``images``): a calibration view's (``board_image``,
    ``laser_image``, ``q_deg``, ``q_reading_deg`` with reading noise, ``standoff_mm``,
    ``tilt_deg``, ``base_cam``, ``circles``, ``stripe``) or a scan frame's (``image``,
    ``stripe``)."""

    board_image: str
    """The board image's file, relative to the dataset."""
    laser_image: str
    """The laser image's file, relative to the dataset."""
    image: str
    """A scan frame's image file, relative to the scan."""
    q_deg: List[float]
    """The true joint angles, degrees."""
    q_reading_deg: List[float]
    """The joint readings written (with their noise), degrees."""
    standoff_mm: float
    """Stand-off along the optical axis to the board plane, mm."""
    tilt_deg: float
    """Angle between the optical axis and the board normal, degrees."""
    base_cam: PoseRecord
    """The true ``T_base_cam`` of the view."""
    circles: List[object]
    """The true target points as the renderer drew them (per point: its grid index and
    pixel position)."""
    stripe: Dict[str, object]
    """The true stripe: ``direction`` and its ``points`` (with ``columns`` naming their
    fields in a scan frame's truth)."""


class TruthExtra(TypedDict, total=False):
    """The twin's keys of truth.json beyond the contract's (``Truth.extra``): which are
    present depends on what was rendered (a calibration dataset, a scan, a verification
    scan); a truth.json written elsewhere may hold others."""

    laser_emitter_mm: List[float]
    """The laser's emitter ``[x, y, z]``, camera frame, mm."""
    stripe_direction: str
    """``"rows"`` or ``"cols"``: how the stripe runs in the images."""
    table: TwinPlane
    """The table plane under the board and the parts."""
    plate: TruthPlate
    """The board plate."""
    sim_config: SimConfig
    """The twin's whole configuration (knobs at their defaults included; groups of
    modes that are off left out)."""
    images: List[TruthImage]
    """Per image, in the dataset's or scan's order."""
    artefact: str
    """A verification scan's artefact name."""
    spheres: List[TruthArtefactSphere]
    """A verification scan's spheres."""
    length_mm: float
    """A ball bar's true length (the spheres' centre distance), mm."""
    plane: TruthArtefactPlane
    """A verification scan's plane."""
    depth_mm: float
    """A verification scan's depth along the optical axis, mm."""


class ProfilerCounts(TypedDict):
    """What one profile written by the profiler mode holds."""

    points: int
    """Points written with a z (spikes included)."""
    sphere: int
    """Of those, on the sphere."""
    table: int
    """Of those, on the table."""
    stand: int
    """Of those, on the sphere's stand."""
    gaps: int
    """Points written as gaps (empty z, ``nan`` or ``invalid_z``)."""
    dropouts: int
    """Of the gaps, random dropouts of valid points (the rest: out of range)."""
    spikes: int
    """Points with a spike."""


class ProfilerViewCounts(ProfilerCounts):
    """A calibration view of the profiler mode: its counts and the true sphere centre."""

    sphere_center_sensor_mm: List[float]
    """The sphere's centre in the sensor frame ``[x, y, z]``, mm."""


class ProfilerSummary(TypedDict):
    """The profiler mode's part of :class:`TwinSummary` (``profiler.enabled``)."""

    views: List[ProfilerViewCounts]
    """Per calibration view."""
    scan: List[ProfilerCounts]
    """Per scan frame."""
    points: int
    """Points written with a z, views and scan."""
    sphere_points: int
    """Of those on the sphere."""
    gaps: int
    """Gaps written, views and scan."""
    spikes: int
    """Spikes written, views and scan."""


class ProfilerPose(TypedDict):
    """A rigid transform as truth.json writes it."""

    rotation_vector: List[float]
    """Rotation vector, radians."""
    translation_mm: List[float]
    """Translation, mm."""


class TwinDhRow(TypedDict, total=False):
    """One DH row as rig.json and truth.json write it (``beta_deg`` only when not 0)."""

    theta0_deg: float
    alpha_deg: float
    a_mm: float
    d_mm: float
    beta_deg: float


class ProfilerRobot(TypedDict):
    """A robot's DH table as truth.json writes it."""

    name: str
    joints: List[TwinDhRow]


class ProfilerStart(TypedDict):
    """What ``stripecal.profiler_start`` returns: the first two steps of a profiler's
    calibration (the arcs, the consensus and its closed-form start)."""

    views: List[int]
    """The views.csv rows kept (0-based)."""
    flanges: F64
    """(N, 4, 4): ``T_base_hand`` of their readings, mm."""
    points: List[F64]
    """Per kept view (M_i, 2): its arc's points ``x_mm, z_mm`` in the profiler frame."""
    hand_sensor: F64
    """(4, 4): the closed-form start's ``T_hand_sensor``."""
    centre_mm: F64
    """(3,): the start's sphere centre, base frame."""
    diameter_mm: float
    """The declared diameter, or the start's when not declared."""
    diameter_free: bool
    """rig.json's ``diameter_mm`` is null (the adjustment estimates it)."""
    warnings: List[str]
    """The views left out, named, and why."""


class ProfilerAdjustment(TypedDict):
    """What ``stripecal.profiler_adjust`` returns: the one-stage adjustment alone (step 3
    of a profiler's calibration, without its checks) from a ``ProfilerStart``."""

    hand_sensor: F64
    """(4, 4): ``T_hand_sensor``, mm."""
    centre_mm: F64
    """(3,): the sphere's centre, base frame."""
    diameter_mm: float
    """The sphere's diameter (the start's when not free)."""
    rms_mm: float
    """RMS distance of the points used from the sphere."""
    points_used: int
    """The points on the sphere after the re-selection."""
    iterations: int
    converged: bool
    view_variance_factor: float
    """The view-clustered variance factor the sigmas carry (>= 1)."""
    sigma: Dict[str, float]
    """One-sigma per estimated number, the calibration file's names."""


class ProfilerTruthView(TypedDict):
    """One profile of a profiler twin's truth.json (``views`` or ``frames``)."""

    profile: str
    """The profile file, relative to the folder."""
    q_deg: List[float]
    """The true joint readings, degrees."""
    base_hand: ProfilerPose
    """The true flange pose ``T_base_hand`` (true robot)."""
    sphere_center_sensor_mm: List[float]
    """The sphere's centre in the sensor frame, mm."""
    tilt_deg: float
    """Angle between the sensor's z and its z at the home pose, degrees."""
    points: ProfilerCounts
    """What the profile file holds."""


class ProfilerStand(TypedDict):
    """The stand under a profiler twin's sphere: a vertical cylinder from the table up."""

    diameter_mm: float
    """Its diameter, mm (0: no stand)."""
    axis_xy_mm: List[float]
    """Its axis' base ``[x, y]``, mm (under the sphere's centre)."""


class ProfilerTruth(TypedDict, total=False):
    """truth.json of a profiler twin (``stripecal.sim.profiler_truth``): ``format``,
    ``sensor``, ``hand_cam``, ``sphere``, ``table``, ``stand``, ``profiler``, ``seed``
    always; ``robot`` with joint readings; ``views`` in ``calib/``, ``frames`` in
    ``scan/``."""

    format: str
    """``"stripecal/truth@1"``."""
    sensor: Dict[str, str]
    """``{"kind": "profiler"}``."""
    hand_cam: ProfilerPose
    """The true ``T_hand_sensor``."""
    robot: ProfilerRobot
    """The TRUE DH rows (rig.json holds the nominal ones); only with joint readings."""
    sphere: TwinSphere
    """The reference sphere, base frame."""
    table: TwinPlane
    """The table plane, base frame (``normal`` up)."""
    stand: ProfilerStand
    """The sphere's stand."""
    profiler: SimProfiler
    """The profiler knobs the twin used (the ``profiler`` part of a :class:`SimConfig`)."""
    seed: int
    """The twin's seed."""
    views: List[ProfilerTruthView]
    """Per calibration view (``calib/truth.json``)."""
    frames: List[ProfilerTruthView]
    """Per scan frame (``scan/truth.json``)."""


class VerifyScan(TypedDict):
    """A verification scan of the twin (``Twin.verify_scans``)."""

    name: str
    """The folder under ``verify/``: ``bar_1``.., ``plate_1``..."""
    artefact: str
    """The artefacts.json name it measures: ``"bar"`` or ``"plate"``."""
    poses: F64
    """Encoder readings (N, J), degrees."""
    spheres: List[TwinSphere]
    """The ball bar's spheres A and B (true, base frame); empty for the plate."""
    plane: Optional[TwinPlane]
    """The plate's true plane; None for the bar."""


class TwinSummary(TypedDict):
    """What ``Twin.write`` wrote."""

    calib_dir: str
    """The calibration dataset folder (rig.json, views.csv, images/, truth.json)."""
    scan_dir: Optional[str]
    """The scan folder, or None when the scan is disabled."""
    views: List[TwinViewSummary]
    """One entry per calibration view."""
    circles_total: int
    """Target points on the board."""
    board_kind: str
    """``"circles"``, ``"asymmetric_circles"`` or ``"chessboard"``."""
    scan_frames: int
    """Scan frames written (0 without a scan)."""
    scan_sphere_points: int
    """Stripe points on the ball over all scan frames."""
    table_dir: Optional[str]
    """The bare-table scan folder (``scan.table``), or None."""
    table_frames: int
    """Frames of the bare-table scan (0 without)."""
    verify_dir: Optional[str]
    """The verification folder (``verify.enabled``: one scan folder per artefact
    position, ``artefacts.json``, ``verify.csv``), or None."""
    verify_frames: int
    """Frames of all verification scans (0 without)."""
    stripe_direction: str
    """``"rows"`` or ``"cols"``: how the stripe runs in the images."""
    sphere: Optional[TwinSphere]
    """The reference ball, or None."""
    profiler: Optional[ProfilerSummary]
    """The profiler mode's counts (``profiler.enabled``; then ``calib_dir`` holds a
    profile dataset and ``scan_dir`` a profile scan), or None."""


class ViewRender(TypedDict):
    """A rendered view or scan frame (``Twin.render_view``, ``Twin.render_scan_frame``)
    with its truth; N target points, M stripe points."""

    board_image: Optional[Gray]
    """The board image (rows, cols), or (rows, cols, 3) RGB for a colour twin
    (``imaging.colour``); None for scan frames."""
    laser_image: Optional[Gray]
    """The laser image (the frame for scans), (rows, cols) or (rows, cols, 3) RGB for a
    colour twin; None in single-image mode."""
    circle_indices: I64
    """Same as ``target_indices`` (historical name)."""
    circle_centers: F64
    """Same as ``target_points`` (historical name)."""
    target_indices: I64
    """Board indices (N, 2) ``(row, col)`` of the imaged target points."""
    target_points: F64
    """True imaged target points (N, 2), px (circles: outline centroids; chessboard:
    the projected corners)."""
    circle_centers_projected: F64
    """Projected target points (N, 2), px (for a chessboard equal to the truth)."""
    stripe_points: F64
    """True stripe points (M, 2), px."""
    stripe_points_cam: F64
    """The stripe points in the camera frame (M, 3), mm."""
    stripe_surface: List[str]
    """The surface each stripe point lies on: ``"board"``, ``"table"`` or ``"sphere"``."""
    stripe_incidence_deg: F64
    """Angle between the surface normal and the direction to the emitter (M,),
    degrees."""
    stripe_view_deg: F64
    """Angle between the surface normal and the direction to the camera (M,),
    degrees."""
    stripe_edge_mm: F64
    """Distance on the surface to the nearest reflectance edge (circle border, square
    side, plate edge) (M,), mm; 99 where there is none nearby."""
    stripe_slope: F64
    """d(other coordinate) / d(scan-line coordinate) of the projected stripe (M,)."""
    base_cam: F64
    """``T_base_cam`` (4, 4) of the view, mm."""


# --- reconstruct / truth: spheres -----------------------------------------------------


class SphereTruth(TypedDict):
    """The true reference ball of a scan (``Truth.sphere``), base frame."""

    center_mm: F64
    """Centre (3,), mm."""
    diameter_mm: float
    """Diameter, mm."""


class SphereInput(TypedDict):
    """What ``Truth(sphere=...)`` accepts: exactly these two keys."""

    center_mm: npt.ArrayLike
    """Centre (3,), mm."""
    diameter_mm: float
    """Diameter, mm."""


class SphereFitExtra(TypedDict, total=False):
    """Other keys of a sphere fit (``SphereFit.extra``), as ``fit_sphere`` writes
    them; a file written elsewhere may lack them or hold others."""

    fit_diameter_sigma_mm: float
    """The fit's one-sigma of the diameter, mm: its random part only (the points'
    scatter); the measurement's uncertainty is ``measure_sphere``'s."""
    fit_center_sigma_mm: List[float]
    """The fit's one-sigma of the centre's components, mm (random part only)."""
    sigma_note: str
    """What the two sigmas are, and where the measurement's uncertainty comes from."""
    diameter_sigma_mm: float
    """``fit_diameter_sigma_mm`` in files written before it was named so."""
    center_sigma_mm: List[float]
    """``fit_center_sigma_mm`` in files written before it was named so."""
    robust_sigma_mm: float
    """Robust sigma of the radial residuals at the last trimming round, mm."""
    max_residual_mm: float
    """Largest absolute radial residual of an inlier, mm."""


SphereFitExtraInput = Union[SphereFitExtra, Dict[str, object]]
"""What ``SphereFit(extra=...)`` accepts: the record or any dict of JSON-like values."""



class Budget(TypedDict):
    """A GUM uncertainty budget of one measured quantity (mm, or degrees for tilts):
    standard uncertainties per part, combined in quadrature, expanded with ``k`` = 2."""

    value_mm: float
    """The measured value (or error, for the characteristics of ``verify``)."""
    expanded_mm: float
    """Expanded uncertainty ``U = k * combined``: the headline."""
    k: float
    """Coverage factor (2)."""
    combined_mm: float
    """Combined standard uncertainty."""
    random_mm: float
    """The fit's own scatter (stripe noise and whatever scatters point to point)."""
    calibration_mm: float
    """The calibration's covariance carried through every point (shared by all points:
    it does not average out)."""
    robot_mm: float
    """The robot's repeatability / encoder figures (shared within a frame)."""
    systematic_mm: float
    """Documented systematic components (the stripe-bias model's remainder, a
    certificate's uncertainty)."""


class SphereBudgets(TypedDict):
    """The budgets of a measured sphere."""

    diameter: Budget
    """Diameter, mm."""
    center: List[Budget]
    """Centre x, y, z (base frame), mm."""
    form: Budget
    """Probing form: range of the radial residuals, mm."""


class StripeBiasInfo(TypedDict):
    """What the curved-surface stripe-bias correction did."""

    sheet_sigma_mm: float
    """The laser sheet's Gaussian sigma estimated from the stripe's width, mm."""
    diameter_change_mm: float
    """Diameter after minus before the correction, mm."""
    points_saturated: int
    """The sphere's points left out of the corrected fit: their stripe holds a saturated
    pixel, and the model has no clipping."""


class CalibrationEmitter(TypedDict):
    """The emitter estimated on the sphere(s), carried into the calibration's board
    stripe-bias correction (docs/measurement.md): the calibration's numbers move to
    the estimate and its emitter range is replaced by the estimate's uncertainty."""

    offset_mm: List[float]
    """The estimate's offsets from the calibration's assumed emitter along the laser
    plane's two in-plane axes, mm."""
    sd_mm: List[float]
    """Their standard uncertainties as used (at least 5 mm), mm."""
    applied: bool
    """Whether the calibration was moved (``False``: see ``reason``)."""
    reason: Optional[str]
    """Why it was not applied (outside the calibration's range, another covariance, the
    calibration part left out); ``None`` when applied."""


class SphereMeasurement(TypedDict):
    """A sphere measured with budgets (``measure_sphere``): the sphere-fit record of
    spec/DATASET.md plus ``uncertainty`` and ``stripe_bias``."""

    diameter_mm: float
    """Diameter, mm (after the bias correction)."""
    center_mm: List[float]
    """Centre (3,), base frame, mm."""
    rms_mm: float
    """RMS of the radial residuals of the inliers, mm."""
    points: int
    """Inliers used."""
    outliers: int
    """Points trimmed."""
    uncertainty: SphereBudgets
    """The budgets."""
    stripe_bias: Optional[StripeBiasInfo]
    """``None`` when the correction was not asked for."""
    calibration_emitter: Optional[CalibrationEmitter]
    """``None`` when no emitter was estimated or the calibration holds no response to
    it (no board stripe-bias correction, or written before it was kept)."""


class BallBarMeasurement(TypedDict):
    """A ball bar measured with budgets (``measure_ball_bar``)."""

    spheres: List[SphereMeasurement]
    """Both spheres."""
    distance: Budget
    """Their centres' distance, mm."""


class PlaneBudgets(TypedDict):
    """The budgets of a measured plane."""

    flatness: Budget
    """Range of the residuals, mm."""
    offset: Budget
    """Offset along the normal (value: ``d_mm``), mm."""
    tilt_deg: List[Budget]
    """The normal's tilts about the two in-plane axes, degrees (value 0)."""


class PlaneMeasurement(TypedDict):
    """A plane measured with budgets (``measure_plane``)."""

    normal: List[float]
    """Unit normal (3,), base frame."""
    d_mm: float
    """``normal . p = d_mm``."""
    rms_mm: float
    """RMS of the residuals, mm."""
    flatness_mm: float
    """Range of the inliers' residuals, mm."""
    points: int
    """Inliers used."""
    outliers: int
    """Points trimmed."""
    uncertainty: PlaneBudgets
    """The budgets."""


class VerifyRow(TypedDict):
    """One measured value of an acceptance-test characteristic."""

    characteristic: str
    """``probing_form``, ``probing_size``, ``sphere_spacing`` or ``flatness``."""
    symbol: str
    """``PF``, ``PS``, ``SD`` or ``F``."""
    scan: str
    """The scan folder (as in verify.csv)."""
    artefact: str
    """What was measured (``bar/A``, ``bar``, ``plate``)."""
    mpe_mm: float
    """The maximum permissible error (artefacts.json)."""
    passed: bool
    """``|value| <= MPE``."""
    conforms: bool
    """``|value| + U <= MPE`` (ISO 14253-1: conformity proven)."""
    budget: Budget
    """The value (an error, or a form) with its budget."""


class VerifySummary(TypedDict):
    """A characteristic over all its measurements."""

    symbol: str
    """``PF``, ``PS``, ``SD`` or ``F``."""
    worst_mm: float
    """The value of largest magnitude, mm."""
    expanded_mm: float
    """Its expanded uncertainty (k = 2), mm."""
    mpe_mm: float
    """The maximum permissible error, mm."""
    measurements: int
    """How many values."""
    passed: bool
    """Every value within the MPE."""
    conforms: bool
    """Every value within the MPE by more than its U."""


class VerifyReport(TypedDict):
    """The VDI/VDE 2634-2 style acceptance test (``verify``): ``stripecal/verify@1``."""

    format: str
    """``stripecal/verify@1``."""
    passed: bool
    """Every measured value within its MPE."""
    summary: Dict[str, VerifySummary]
    """Per characteristic key (``probing_form``, ...), those measured."""
    rows: List[VerifyRow]
    """Every measured value, in manifest order."""
