"""stripecal.detect_circles (issue 3): API, bad input, and the comparison with OpenCV's
cv2.findCirclesGrid on the same twin images (acceptance 4 and 7)."""

from __future__ import annotations

from typing import Any, Dict, List, Tuple

import numpy as np
import numpy.typing as npt
import pytest

import stripecal
import stripecal.sim as sim

F64 = npt.NDArray[np.float64]


@pytest.fixture(scope="module")
def views() -> List[Dict[str, Any]]:
    """Board images of the hp3-paper twin's calibration poses (two seeds, 10 views)."""
    out = []
    for seed in (0, 1):
        twin = sim.Twin(sim.preset("hp3-paper", seed=seed))
        for i, pose in enumerate(twin.calibration_poses()):
            v = twin.render_view(pose["q_deg"], i)
            v["board"] = twin.board
            out.append(v)
    return out


def errors_by_index(idx: npt.NDArray[np.int64], ctr: F64, view: Dict[str, Any]) -> F64:
    truth = {(int(r), int(c)): p for (r, c), p in zip(view["circle_indices"], view["circle_centers"])}
    return np.array([np.hypot(*(p - truth[(int(r), int(c))])) for (r, c), p in zip(idx, ctr)])


def test_types_shapes_and_accuracy(views: List[Dict[str, Any]]) -> None:
    v = views[0]
    idx, ctr = stripecal.detect_circles(v["board_image"], v["board"])
    assert idx.dtype == np.int64 and idx.shape == (88, 2)
    assert ctr.dtype == np.float64 and ctr.shape == (88, 2)
    # sorted by (row, col), every circle once
    assert [tuple(x) for x in idx] == [(r, c) for r in range(8) for c in range(11)]
    e = errors_by_index(idx, ctr, v)
    assert np.sqrt(np.mean(e**2)) < 0.015 and e.max() < 0.05


def test_full_result_and_methods(views: List[Dict[str, Any]]) -> None:
    v = views[1]
    full = stripecal.detect_circles_full(v["board_image"], v["board"], method="ellipse")
    n = len(full["indices"])
    assert n == 88 and full["method"] == "ellipse"
    for key, shape in [("centres", (n, 2)), ("quality_px", (n,)), ("area_px", (n,)), ("axes_px", (n, 2)), ("angle_rad", (n,))]:
        assert full[key].shape == shape and full[key].dtype == np.float64, key
    assert full["stripe_crossed"].dtype == np.bool_ and not full["stripe_crossed"].any()
    assert full["dropped"] == [] and full["blobs"] >= 88
    assert np.all(full["quality_px"] < 0.1)
    # markers are about twice the area of ordinary circles
    area = dict(zip(map(tuple, full["indices"]), full["area_px"]))
    assert 1.6 < area[(0, 0)] / area[(1, 1)] < 2.4
    e = errors_by_index(full["indices"], full["centres"], v)
    assert np.sqrt(np.mean(e**2)) < 0.015
    with pytest.raises(stripecal.InvalidInputError, match="method"):
        stripecal.detect_circles(v["board_image"], v["board"], method="hough")


def test_any_layout_and_depth(views: List[Dict[str, Any]]) -> None:
    v = views[2]
    img = v["board_image"]
    idx, ctr = stripecal.detect_circles(img, v["board"])
    # strided views (Fortran order, a padded slice) give the same result
    for other in (np.asfortranarray(img), np.pad(img, ((0, 0), (0, 5)))[:, : img.shape[1]]):
        i2, c2 = stripecal.detect_circles(other, v["board"])
        assert np.array_equal(i2, idx) and np.allclose(c2, ctr)
    # 16-bit images work (full range)
    i16, c16 = stripecal.detect_circles(img.astype(np.uint16) * 257, v["board"])
    assert np.array_equal(i16, idx) and np.allclose(c16, ctr, atol=1e-6)


@pytest.mark.parametrize(
    "name,image,exc",
    [
        ("empty", np.zeros((0, 0), np.uint8), stripecal.InvalidInputError),
        ("1-pixel", np.zeros((1, 1), np.uint8), stripecal.InvalidInputError),
        ("3D array", np.zeros((48, 64, 3), np.uint8), stripecal.InvalidInputError),
        ("float image", np.zeros((48, 64), np.float64), TypeError),
        ("int32 image", np.zeros((48, 64), np.int32), TypeError),
        ("list", [[0, 1], [2, 3]], TypeError),
        ("all-black", np.zeros((576, 768), np.uint8), stripecal.DetectionError),
        ("all-white", np.full((576, 768), 255, np.uint8), stripecal.DetectionError),
        ("all-white 16-bit", np.full((576, 768), 65535, np.uint16), stripecal.DetectionError),
        ("noise only", np.random.default_rng(0).integers(0, 256, (576, 768)).astype(np.uint8), stripecal.DetectionError),
        ("dark noise", np.random.default_rng(1).normal(20, 3, (576, 768)).clip(0, 255).astype(np.uint8), stripecal.DetectionError),
    ],
)
def test_bad_input_is_a_typed_error(name: str, image: Any, exc: type) -> None:
    board = stripecal.Board(8, 11, 5.0, 2.5, 3.5)
    with pytest.raises(exc) as info:
        stripecal.detect_circles(image, board)
    assert str(info.value), name
    # the library's own errors are also ValueError
    if exc is not TypeError:
        assert isinstance(info.value, ValueError)


def test_board_argument_is_checked(views: List[Dict[str, Any]]) -> None:
    img = views[0]["board_image"]
    with pytest.raises(TypeError):
        stripecal.detect_circles(img, "hp3")  # type: ignore[arg-type]
    chess = stripecal.Board(8, 11, 5.0, 2.5, 3.5, kind="chessboard", square_mm=5.0)
    with pytest.raises(stripecal.InvalidInputError, match="circle board"):
        stripecal.detect_circles(img, chess)
    # markers too similar to the circles cannot fix the grid
    same = stripecal.Board(8, 11, 5.0, 2.5, 2.55)
    with pytest.raises(stripecal.InvalidInputError, match="markers"):
        stripecal.detect_circles(img, same)


def opencv_centres(cv2: Any, img: npt.NDArray[np.uint8], board: stripecal.Board) -> F64 | None:
    """cv2.findCirclesGrid (symmetric grid, its default SimpleBlobDetector, which finds
    these dark blobs), or None when it fails."""
    ok, c = cv2.findCirclesGrid(img, (board.cols, board.rows), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
    if not ok or c is None:
        return None
    return np.asarray(c, np.float64).reshape(-1, 2)


def nearest_errors(pts: F64, truth: F64) -> F64:
    d = np.linalg.norm(pts[:, None, :] - truth[None, :, :], axis=2)
    return np.asarray(d.min(axis=1))


def test_accuracy_against_opencv(views: List[Dict[str, Any]]) -> None:
    """Acceptance 4: the same twin images through cv2.findCirclesGrid; both centre errors
    against the truth are printed; ours must be no worse (RMS and max)."""
    cv2 = pytest.importorskip("cv2")
    ours: List[F64] = []
    theirs: List[F64] = []
    ours_same: List[F64] = []
    failed = 0
    for v in views:
        img, truth = v["board_image"], v["circle_centers"]
        idx, ctr = stripecal.detect_circles(img, v["board"])
        e = errors_by_index(idx, ctr, v)
        ours.append(e)
        oc = opencv_centres(cv2, img, v["board"])
        if oc is None:
            failed += 1
            continue
        en = nearest_errors(oc, truth)
        assert en.max() < 2.0, "OpenCV's points match the truth circles"
        theirs.append(en)
        ours_same.append(e)

    def row(name: str, es: List[F64]) -> Tuple[str, int, float, float]:
        a = np.concatenate(es) if es else np.zeros(0)
        return name, a.size, float(np.sqrt(np.mean(a**2))) if a.size else float("nan"), float(a.max()) if a.size else float("nan")

    table = [row("stripecal (gravity)", ours), row("stripecal, same views", ours_same), row("cv2.findCirclesGrid", theirs)]
    print(f"\ncircle centres vs truth, hp3-paper twin, {len(views)} views (OpenCV failed on {failed}):")
    print(f"{'detector':<24} {'circles':>7} {'RMS px':>8} {'max px':>8}")
    for name, n, rms, mx in table:
        print(f"{name:<24} {n:>7} {rms:>8.4f} {mx:>8.4f}")
    assert theirs, "OpenCV found no grid at all"
    _, _, rms_ours, max_ours = table[1]
    _, _, rms_cv, max_cv = table[2]
    assert rms_ours <= rms_cv and max_ours <= max_cv
