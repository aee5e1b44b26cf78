"""Colour lasers (issue 17): rig.json's ``stripe.channel``, the stripe found in the laser
colour's channel of colour laser images, ``auto``, and the twin's colour images.

Acceptance (issue 17, item 2): a colour twin (red line over the white circle board,
noise 1 gray level per channel, PSF 0.7 px) calibrated with ``channel: red`` has at
most half the stripe residual of the same images after the BT.601 gray conversion, and
its laser plane within 0.01 mm of the truth; the sub-pixel quality in the red channel is
that of an equivalent gray image. Bad input (item 5, the colour part): an unknown colour
names rig.json and the key, a colour name with gray laser images names the file.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any, Dict, List, Tuple

import numpy as np
import pytest

import stripecal
import stripecal.sim

SEED = 2


def _twin(colour: bool, **kw: Any) -> stripecal.sim.Twin:
    imaging: Dict[str, Any] = {"colour": colour, "laser_colour": "red", "noise_gray": 1.0, "psf_sigma_px": 0.7}
    imaging.update(kw.pop("imaging", {}))
    return stripecal.sim.Twin(stripecal.sim.preset("hp3-paper", seed=SEED, imaging=imaging, **kw))


@pytest.fixture(scope="module")
def colour_twin(tmp_path_factory: pytest.TempPathFactory) -> Tuple[stripecal.sim.Twin, Path]:
    """The colour twin rendered once: 5 calibration views and a short ball scan."""
    out = tmp_path_factory.mktemp("colour")
    twin = _twin(True, scan={"max_frames": 6})
    twin.write(out)
    return twin, out


def _with_channel(src: Path, dst: Path, channel: str) -> Path:
    """A copy of the dataset folder `src` whose rig.json says `stripe.channel`."""
    shutil.copytree(src, dst)
    rig = json.loads((dst / "rig.json").read_text())
    rig.setdefault("stripe", {})["channel"] = channel
    (dst / "rig.json").write_text(json.dumps(rig))
    return dst


def _plane_errors_mm(cal: stripecal.Calibration, truth: stripecal.Truth) -> Tuple[float, float]:
    """|d - d_true|, and the largest distance from the estimated plane of the true
    plane's points that the camera sees within the working range (the plane at the
    working distance), mm."""
    n, d = (np.asarray(x, float) for x in cal.laser_plane)
    nt, dt = (np.asarray(x, float) for x in truth.laser_plane)
    cam = truth.camera
    us, vs = np.meshgrid(np.linspace(0, cam.width - 1, 25), np.linspace(0, cam.height - 1, 25))
    rays = np.stack([(us.ravel() - cam.u0) / cam.fu, (vs.ravel() - cam.v0) / cam.fv, np.ones(us.size)], 1)
    t = float(dt) / (rays @ nt)
    p = rays * t[:, None]
    lo, hi = truth.working_range_mm
    p = p[(t > 0) & (p[:, 2] >= lo) & (p[:, 2] <= hi)]
    assert len(p) > 20
    return abs(float(d) - float(dt)), float(np.max(np.abs(p @ n - d)))


def test_colour_twin_writes_rgb_images_and_the_channel(colour_twin: Tuple[stripecal.sim.Twin, Path]) -> None:
    twin, out = colour_twin
    calib = out / "calib"
    rig = stripecal.load_dataset(calib).rig
    assert rig.stripe_channel == "red"
    assert json.loads((calib / "rig.json").read_text())["stripe"]["channel"] == "red"
    laser = stripecal.load_image(calib / "images" / "view_000_laser.png", colour=True)
    assert laser.shape == (576, 768, 3) and laser.dtype == np.uint8
    gray = stripecal.load_image(calib / "images" / "view_000_laser.png")
    assert gray.shape == (576, 768)
    # BT.601 luma, rounded
    r, g, b = (laser[..., k].astype(np.int64) for k in range(3))
    assert np.array_equal(gray, (299 * r + 587 * g + 114 * b + 500) // 1000)
    # the laser is in the red channel only: red stands out along the stripe, green and
    # blue differ by their noise only (white board, white ambient)
    assert np.count_nonzero(r - g > 50) > 500
    assert np.percentile(np.abs(g - b), 99.9) < 7
    assert (out / "scan" / "rig.json").exists()
    frame = stripecal.load_image(out / "scan" / "images" / "scan_0000.png", colour=True)
    assert frame.shape == (576, 768, 3)


def test_red_halves_the_stripe_residual_and_keeps_the_plane(
    colour_twin: Tuple[stripecal.sim.Twin, Path], tmp_path: Path
) -> None:
    _, out = colour_twin
    truth = stripecal.load_truth(out / "calib" / "truth.json")
    red = stripecal.calibrate(_with_channel(out / "calib", tmp_path / "red", "red"))
    gray = stripecal.calibrate(_with_channel(out / "calib", tmp_path / "gray", "gray"))
    rms_red, rms_gray = red.quality["stripe_rms_px"], gray.quality["stripe_rms_px"]
    assert rms_red <= 0.5 * rms_gray, (rms_red, rms_gray)
    assert red.extra["stripe_channel"] == "red"
    assert "stripe_channel" not in gray.extra
    d_err, wd_err = _plane_errors_mm(red, truth)
    assert d_err <= 0.01 and wd_err <= 0.01, (d_err, wd_err)
    # every view used, about as many stripe points as in gray
    assert red.quality["views_used"] == gray.quality["views_used"] == 5


def test_auto_chooses_red_for_a_red_laser_and_gray_for_gray_images(
    colour_twin: Tuple[stripecal.sim.Twin, Path], tmp_path: Path
) -> None:
    _, out = colour_twin
    auto = stripecal.calibrate(_with_channel(out / "calib", tmp_path / "auto", "auto"))
    assert auto.extra["stripe_channel"] == "red"
    scores = auto.extra["stripe_channel_scores"]
    assert set(scores) == {"gray", "red", "green", "blue"}
    assert scores["red"] > 1.5 * scores["gray"] > 0 and scores["green"] < 0.05 * scores["red"]
    # per image: the same choice, and the same stripe as with "red"
    view = _twin(True, scan={"enabled": False}).render_view(_twin(False).calibration_poses()[0]["q_deg"])
    a = stripecal.extract_stripe(view["laser_image"], channel="auto")
    r = stripecal.extract_stripe(view["laser_image"], channel="red")
    assert np.array_equal(a.points, r.points)
    # gray laser images: auto is gray
    gray_out = tmp_path / "gray_twin"
    _twin(False, poses={"count": 4}, scan={"enabled": False}).write(gray_out)
    cal = stripecal.calibrate(_with_channel(gray_out / "calib", tmp_path / "gray_auto", "auto"))
    assert cal.extra["stripe_channel"] == "gray"
    assert cal.extra["stripe_channel_scores"]["red"] == 0


def _errors_against_truth(stripe: stripecal.Stripe, view: Dict[str, Any], direction: str) -> np.ndarray:
    """Along-scan-line errors (px) of the trusted stripe points against the true centre
    line of the same scan line on the board."""
    on_board = np.array([s == "board" for s in view["stripe_surface"]])
    t = view["stripe_points"][on_board]
    # direction "cols": one point per row (scan line v, position u); "rows": per column
    line, pos = (1, 0) if direction == "cols" else (0, 1)
    truth = {int(round(p[line])): p[pos] for p in t}
    pts = stripe.points[stripe.trusted]
    return np.array([p[pos] - truth[int(round(p[line]))] for p in pts if int(round(p[line])) in truth])


def test_subpixel_quality_in_the_laser_colour_equals_gray_on_equivalent_gray_images() -> None:
    # The red channel of a colour laser image is a gray laser image of the same laser and
    # ambient with its own noise: the same extractor gives the same sub-pixel quality on
    # it as on the gray twin's image of the same view; BT.601 gray of the colour image is
    # far worse. The spread is the robust one (1.4826 x the median absolute error): a few
    # points near the circles' edges, the same in both, would dominate an RMS of 5 views.
    colour = _twin(True, scan={"enabled": False})
    gray = _twin(False, scan={"enabled": False})
    direction = colour.stripe_direction
    err: Dict[str, List[np.ndarray]] = {"red": [], "gray_equiv": [], "bt601": []}
    for i, pose in enumerate(colour.calibration_poses()):
        vc = colour.render_view(pose["q_deg"], i)
        vg = gray.render_view(pose["q_deg"], i)
        for key, img, board in (
            ("red", vc["laser_image"], vc["board_image"]),
            ("bt601", vc["laser_image"], vc["board_image"]),
            ("gray_equiv", vg["laser_image"], vg["board_image"]),
        ):
            ch = "red" if key == "red" else "gray"
            s = stripecal.extract_stripe(img, direction=direction, board_image=board, channel=ch)
            err[key].append(_errors_against_truth(s, vc, direction))
    rms = {k: 1.4826 * float(np.median(np.abs(np.concatenate(v)))) for k, v in err.items()}
    n = {k: sum(len(e) for e in v) for k, v in err.items()}
    assert 0.85 <= rms["red"] / rms["gray_equiv"] <= 1.15, rms
    assert abs(n["red"] - n["gray_equiv"]) <= 0.05 * n["gray_equiv"], n
    assert rms["red"] <= 0.65 * rms["bt601"], rms


def test_colour_scan_reconstructs_in_the_rig_channel(colour_twin: Tuple[stripecal.sim.Twin, Path]) -> None:
    twin, out = colour_twin
    cal = stripecal.calibrate(out / "calib")
    red = stripecal.reconstruct_scan(cal, out / "scan")  # the scan's rig.json: red
    forced = stripecal.reconstruct_scan(cal, out / "scan", channel="red")
    gray = stripecal.reconstruct_scan(cal, out / "scan", channel="gray")
    auto = stripecal.reconstruct_scan(cal, out / "scan", channel="auto")
    assert len(red) > 0 and np.array_equal(red.points, forced.points)
    assert np.array_equal(auto.points, red.points)
    assert len(gray) > 0
    # the stripe's peak in red is ~1 / 0.299 of its gray peak
    assert np.median(red.intensity) > 2.5 * np.median(gray.intensity)
    # in-memory frames: (N, H, W, 3) arrays and the same channel give the same points
    frames = [stripecal.load_image(out / "scan" / "images" / f"scan_{k:04d}.png", colour=True) for k in range(6)]
    scan = stripecal.load_scan(out / "scan")
    joints = np.asarray(scan.joints)[:6]
    mem = stripecal.reconstruct(cal, np.stack(frames), joints, channel="red")
    assert np.allclose(mem.points, red.points)


# ---------------------------------------------------------------- bad input (item 5)


def test_unknown_colour_names_rig_json_and_the_key(colour_twin: Tuple[stripecal.sim.Twin, Path], tmp_path: Path) -> None:
    _, out = colour_twin
    bad = _with_channel(out / "calib", tmp_path / "purple", "purple")
    with pytest.raises(stripecal.FormatError, match=r"rig\.json: stripe\.channel: unknown laser colour \"purple\"") as e:
        stripecal.calibrate(bad)
    assert str(bad / "rig.json") in str(e.value)
    with pytest.raises(stripecal.FormatError, match="rig.json.*stripe.channel"):
        stripecal.load_dataset(bad)
    with pytest.raises(stripecal.InvalidInputError, match="purple"):
        stripecal.extract_stripe(np.zeros((8, 8, 3), np.uint8), channel="purple")
    board = stripecal.load_dataset(out / "calib").rig.board
    with pytest.raises(stripecal.InvalidInputError, match="stripe channel"):
        stripecal.Rig((768, 576), board, stripe_channel="infrared")
    with pytest.raises(stripecal.InvalidInputError, match="purple"):
        stripecal.reconstruct_scan(stripecal.calibrate(out / "calib"), out / "scan", channel="purple")


def test_colour_name_with_gray_laser_images_names_the_file(tmp_path: Path) -> None:
    out = tmp_path / "gray"
    _twin(False, poses={"count": 4}, scan={"max_frames": 2}).write(out)
    bad = _with_channel(out / "calib", tmp_path / "red_on_gray", "red")
    with pytest.raises(stripecal.FormatError, match=r"view_000_laser\.png: stripe\.channel \"red\": a gray laser image") as e:
        stripecal.calibrate(bad)
    assert str(bad / "images" / "view_000_laser.png") in str(e.value)
    cal = stripecal.calibrate(out / "calib")
    with pytest.raises(stripecal.FormatError, match=r"scan_0000\.png: stripe\.channel \"green\""):
        stripecal.reconstruct_scan(cal, out / "scan", channel="green")
    with pytest.raises(stripecal.InvalidInputError, match="channel \"blue\" needs a colour image"):
        stripecal.extract_stripe(np.zeros((8, 8), np.uint8), channel="blue")


def test_rig_stripe_channel_round_trips() -> None:
    board = stripecal.Board.hp3_paper()
    for ch in ("gray", "red", "green", "blue", "auto"):
        rig = stripecal.Rig((768, 576), board, stripe_channel=ch)
        assert rig.stripe_channel == ch
        back = stripecal.Rig.from_json(rig.to_json())
        assert back == rig and back.stripe_channel == ch
        assert ('"channel"' in rig.to_json()) == (ch != "gray")
    assert stripecal.Rig((768, 576), board).stripe_channel == "gray"
    assert "stripe_channel='green'" in repr(stripecal.Rig((768, 576), board, stripe_channel="green"))
