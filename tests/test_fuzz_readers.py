"""Property tests of the file readers and pose conversions through the public Python API
(issue 13, acceptance 4; docs/robustness.md).

Arbitrary bytes, arbitrary text and nearly valid documents go through ``load_rig``,
``load_dataset``, ``load_scan``, ``load_calibration``, ``load_truth``,
``load_sphere_fit``, ``read_ply``, ``load_image``, ``read_profile``,
``load_profile_dataset``, ``read_profiler_calibration``, ``pose_to_matrix`` and
``matrix_to_pose``: only ``stripecal.StripecalError`` subclasses or ``OSError`` may come
out (``TypeError`` for arguments of the wrong type), never another exception and in
particular never ``pyo3_runtime.PanicException`` (a Rust panic crossing into Python).
Whatever a reader accepts is valid (finite poses, images whose shape matches their
size) and goes back through its writer. Pose conventions round-trip as rotation
MATRICES.

Budget: the ``stripecal-fuzz`` profile runs ``200 * STRIPECAL_FUZZ_CASES`` examples per
property (default 1) with ``deadline=None``, derandomised (the same examples every run,
no example database), so a failure reproduces; hypothesis prints the failing example.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import stripecal

SCALE = int(os.environ.get("STRIPECAL_FUZZ_CASES", "1") or "1")
settings.register_profile(
    "stripecal-fuzz",
    max_examples=200 * max(SCALE, 1),
    deadline=None,
    derandomize=True,
    database=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
FUZZ = settings.get_profile("stripecal-fuzz")

#: What a reader may raise on bad input.
ALLOWED = (stripecal.StripecalError, OSError)


def call(fn: Callable[..., Any], *args: Any, allow_type_error: bool = False) -> Any:
    """``fn(*args)``, or ``None`` when it raised an allowed error; anything else (a
    ``PanicException``, a ``RuntimeError``, ``KeyError``...) fails the test."""
    allowed: tuple[type[BaseException], ...] = ALLOWED + ((TypeError,) if allow_type_error else ())
    try:
        return fn(*args)
    except allowed as e:
        assert str(e).strip(), f"{fn.__name__}: empty error message"
        return None
    except BaseException as e:  # a PanicException derives from BaseException
        pytest.fail(f"{fn.__name__}{args!r:.300}: {type(e).__module__}.{type(e).__name__}: {e}")


def write(dirname: str, name: str, data: bytes) -> Path:
    p = Path(dirname) / name
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_bytes(data)
    return p


def finite(a: Any) -> bool:
    return bool(np.all(np.isfinite(np.asarray(a, dtype=float))))


def is_rigid(m: np.ndarray) -> bool:
    r = m[:3, :3]
    return (
        m.shape == (4, 4)
        and finite(m)
        and np.allclose(r.T @ r, np.eye(3), atol=1e-9)
        and np.allclose(m[3], [0, 0, 0, 1])
        and np.linalg.det(r) > 0
    )


RIG = {
    "format": "stripecal/rig@1",
    "camera": {"width": 768, "height": 576, "distortion_model": "radial1"},
    "board": {
        "rows": 8,
        "cols": 11,
        "pitch_mm": 5.0,
        "circle_diameter_mm": 2.5,
        "marker_diameter_mm": 3.5,
        "markers": [[0, 0], [0, 1], [1, 0]],
        "dark_circles": True,
    },
    "robot": {
        "name": "MOTOMAN HP3",
        "joints": [
            {"theta0_deg": 0, "alpha_deg": -90, "a_mm": 100, "d_mm": 0},
            {"theta0_deg": 90, "alpha_deg": 180, "a_mm": 370, "d_mm": 0},
            {"theta0_deg": 0, "alpha_deg": -90, "a_mm": 85, "d_mm": 0},
            {"theta0_deg": 0, "alpha_deg": 90, "a_mm": 0, "d_mm": -380},
            {"theta0_deg": -180, "alpha_deg": 90, "a_mm": 0, "d_mm": 0},
            {"theta0_deg": -180, "alpha_deg": 180, "a_mm": 0, "d_mm": -90},
        ],
    },
    "stripe": {"direction": "auto"},
}

CALIBRATION = {
    "format": "stripecal/calibration@1",
    "camera": {"width": 768, "height": 576, "fu": 1271.65, "fv": 1322.52, "u0": 346.14,
               "v0": 262.60, "distortion_model": "radial1", "distortion": [0.0002, 0, 0, 0, 0]},
    "laser_plane": {"normal": [0.629, -0.0492, 0.7759], "d_mm": 79.87},
    "hand_cam": {"rotation_vector": [-0.3087, 0.2362, 3.0369], "translation_mm": [29.19, 5.37, 62.64]},
    "base_board": {"rotation_vector": [0, 0, 0], "translation_mm": [0, 0, 0]},
    "robot": RIG["robot"],
    "quality": {"circle_rms_px": 0.0, "stripe_rms_px": 0.0, "views_used": 5},
    "uncertainty": {"camera": {"fu": 0.1}},
    "covariance": {"parameters": ["camera.fu", "camera.fv"], "matrix": [[0.01, 0.0], [0.0, 0.02]]},
}

#: The columns of the named pose conventions (spec/DATASET.md).
HEADERS = {
    "quaternion": "x_mm,y_mm,z_mm,qw,qx,qy,qz",
    "ros": "x_m,y_m,z_m,qx,qy,qz,qw",
    "rotvec": "x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad",
    "rotvec_deg": "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg",
    "ur": "x_m,y_m,z_m,rx_rad,ry_rad,rz_rad",
    "kuka": "x_mm,y_mm,z_mm,a_deg,b_deg,c_deg",
    "fanuc": "x_mm,y_mm,z_mm,w_deg,p_deg,r_deg",
    "matrix": "x_mm,y_mm,z_mm,r11,r12,r13,r21,r22,r23,r31,r32,r33",
}

CONVENTIONS = ["quaternion", "ros", "rotvec", "rotvec_deg", "ur", "kuka", "fanuc", "matrix"]

json_leaf = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=False, allow_infinity=False),
    st.sampled_from([0, -1, 1e308, -0.0, 2.5, 8, 1000, 1001]),
    st.text(max_size=8),
    st.sampled_from(["circles", "chessboard", "radial1", "opencv5", "rows", "stripecal/rig@1"]),
)
json_value = st.recursive(
    json_leaf,
    lambda inner: st.one_of(
        st.lists(inner, max_size=5),
        st.dictionaries(st.sampled_from(["rows", "cols", "width", "pitch_mm", "joints", "markers", "x"]), inner, max_size=4),
    ),
    max_leaves=20,
)


def edit(doc: Any, path: list[int], new: Any) -> Any:
    """``doc`` with the subtree chosen by ``path`` replaced by ``new`` (or removed)."""
    if not path:
        return new
    k, rest = path[0], path[1:]
    if isinstance(doc, dict) and doc:
        key = sorted(doc)[k % len(doc)]
        out = dict(doc)
        if k % 7 == 1:
            del out[key]
        else:
            out[key] = edit(doc[key], rest, new)
        return out
    if isinstance(doc, list) and doc:
        out_l = list(doc)
        out_l[k % len(doc)] = edit(doc[k % len(doc)], rest, new)
        return out_l
    return new


# ------------------------------------------------------------------ readers, bytes


@FUZZ
@given(data=st.binary(max_size=600), which=st.integers(0, 7))
def test_readers_take_arbitrary_bytes(data: bytes, which: int) -> None:
    readers = [
        ("rig.json", stripecal.load_rig),
        ("calibration.json", stripecal.load_calibration),
        ("truth.json", stripecal.load_truth),
        ("sphere.json", stripecal.load_sphere_fit),
        ("cloud.ply", stripecal.read_ply),
        ("image.png", stripecal.load_image),
        ("profile.csv", stripecal.read_profile),
        ("calibration.json", stripecal.read_profiler_calibration),
    ]
    name, fn = readers[which]
    with tempfile.TemporaryDirectory() as d:
        out = call(fn, write(d, name, data))
    if fn is stripecal.load_image and out is not None:
        assert out.ndim == 2 and out.size > 0


@FUZZ
@given(
    magic=st.sampled_from([b"", b"\x89PNG\r\n\x1a\n", b"II*\x00", b"MM\x00*", b"BM", b"\xff\xd8\xff"]),
    data=st.binary(max_size=300),
)
def test_load_image_takes_arbitrary_bytes_after_a_magic_number(magic: bytes, data: bytes) -> None:
    with tempfile.TemporaryDirectory() as d:
        out = call(stripecal.load_image, write(d, "img.bin", magic + data))
    if out is not None:
        assert out.ndim == 2 and out.size > 0 and out.dtype in (np.uint8, np.uint16)


@FUZZ
@given(path=st.lists(st.integers(0, 1000), min_size=1, max_size=4), new=json_value)
def test_load_rig_with_one_random_edit(path: list[int], new: Any) -> None:
    text = json.dumps(edit(RIG, path, new))
    with tempfile.TemporaryDirectory() as d:
        rig = call(stripecal.load_rig, write(d, "rig.json", text.encode()))
        if rig is not None:
            # what was read is written back and read again
            stripecal.save_rig(Path(d) / "again.json", rig)
            assert stripecal.load_rig(Path(d) / "again.json") is not None


@FUZZ
@given(path=st.lists(st.integers(0, 1000), min_size=1, max_size=4), new=json_value)
def test_load_calibration_with_one_random_edit(path: list[int], new: Any, calibration_text: str) -> None:
    text = json.dumps(edit(json.loads(calibration_text), path, new))
    with tempfile.TemporaryDirectory() as d:
        cal = call(stripecal.load_calibration, write(d, "calibration.json", text.encode()))
        if cal is not None:
            assert finite(cal.hand_cam) and finite(cal.base_board)
            stripecal.save_calibration(Path(d) / "again.json", cal)
            stripecal.load_calibration(Path(d) / "again.json")


@pytest.fixture(scope="module")
def calibration_text() -> str:
    # the contract's example, read and written once (so it has every key the writer writes)
    with tempfile.TemporaryDirectory() as d:
        p = write(d, "in.json", json.dumps(CALIBRATION).encode())
        out = Path(d) / "calibration.json"
        stripecal.save_calibration(out, stripecal.load_calibration(p))
        return out.read_text()


# ------------------------------------------------------------------ datasets

csv_field = st.one_of(
    st.sampled_from(["0", "-90", "1.5", "nan", "inf", "1e308", "", "-0", "x", "18446744073709551616"]),
    st.floats().map(repr),
    st.text(max_size=5),
)


@FUZZ
@given(
    header=st.one_of(
        st.just("board_image,laser_image,q1,q2,q3,q4,q5,q6"),
        st.sampled_from(CONVENTIONS).map(lambda c: "board_image,laser_image," + HEADERS[c]),
        st.lists(st.sampled_from(["board_image", "laser_image", "q1", "x_mm", "qw", "r11", "a_deg", ""]), max_size=9).map(",".join),
    ),
    rows=st.lists(st.lists(csv_field, max_size=14), max_size=4),
    crlf=st.booleans(),
    rig_edit=st.one_of(st.none(), st.tuples(st.lists(st.integers(0, 1000), min_size=1, max_size=3), json_value)),
)
def test_load_dataset_and_scan_take_arbitrary_tables(
    header: str, rows: list[list[str]], crlf: bool, rig_edit: Any
) -> None:
    nl = "\r\n" if crlf else "\n"
    body = nl.join([header] + [",".join(["images/a.png", "images/a.png"] + r) for r in rows])
    rig = RIG if rig_edit is None else edit(RIG, rig_edit[0], rig_edit[1])
    with tempfile.TemporaryDirectory() as d:
        write(d, "rig.json", json.dumps(rig).encode())
        write(d, "views.csv", body.encode())
        write(d, "images/a.png", b"not decoded by load_dataset")
        ds = call(stripecal.load_dataset, d)
        if ds is not None:
            assert len(ds.views) >= 1
        scan_body = nl.join(["image" + header[len("board_image,laser_image"):]] + [",".join(["images/a.png"] + r) for r in rows])
        write(d, "scan.csv", scan_body.encode())
        call(stripecal.load_scan, d)


PROFILER_RIG = {
    "format": "stripecal/rig@1",
    "sensor": {"kind": "profiler", "invalid_z": -99999.9999},
    "artefact": {"kind": "sphere", "diameter_mm": 80.0},
    "robot": RIG["robot"],
}


@FUZZ
@given(
    header=st.one_of(
        st.just("x_mm,z_mm"),
        st.just("intensity,z_mm,x_mm"),
        st.lists(st.sampled_from(["x_mm", "z_mm", "intensity", "", "x"]), max_size=4).map(",".join),
    ),
    rows=st.lists(st.lists(csv_field, max_size=4), max_size=6),
    crlf=st.booleans(),
    invalid_z=st.one_of(st.none(), st.sampled_from([-99999.9999, 0.0, float("nan")])),
)
def test_read_profile_takes_arbitrary_tables(
    header: str, rows: list[list[str]], crlf: bool, invalid_z: Any
) -> None:
    nl = "\r\n" if crlf else "\n"
    body = nl.join([header] + [",".join(r) for r in rows])
    with tempfile.TemporaryDirectory() as d:
        prof = call(stripecal.read_profile, write(d, "p.csv", body.encode()), invalid_z)
    if prof is not None:
        # what is accepted is finite points plus counted gaps, one per data line
        assert prof.points.shape[1] == 2 and finite(prof.points)
        assert len(prof) + prof.gaps <= len(rows)


@FUZZ
@given(
    header=st.one_of(
        st.just("profile,q1,q2,q3,q4,q5,q6"),
        st.sampled_from(CONVENTIONS).map(lambda c: "profile," + HEADERS[c]),
        st.lists(st.sampled_from(["profile", "board_image", "image", "q1", "x_mm", "qw", ""]), max_size=8).map(",".join),
    ),
    rows=st.lists(st.lists(csv_field, max_size=13), max_size=4),
    rig_edit=st.one_of(st.none(), st.tuples(st.lists(st.integers(0, 1000), min_size=1, max_size=3), json_value)),
)
def test_load_profile_dataset_takes_arbitrary_tables(header: str, rows: list[list[str]], rig_edit: Any) -> None:
    body = "\n".join([header] + [",".join(["p/a.csv"] + r) for r in rows])
    rig = PROFILER_RIG if rig_edit is None else edit(PROFILER_RIG, rig_edit[0], rig_edit[1])
    with tempfile.TemporaryDirectory() as d:
        write(d, "rig.json", json.dumps(rig).encode())
        write(d, "views.csv", body.encode())
        write(d, "p/a.csv", b"x_mm,z_mm\n0,200\n")
        ds = call(stripecal.load_profile_dataset, d)
        if ds is not None:
            assert len(ds) >= 1
            assert (ds.joints is None) != (ds.flange_poses is None)
            poses = ds.flange_poses
            if poses is not None:
                assert all(is_rigid(m) for m in poses)


# ------------------------------------------------------------------ PLY


@FUZZ
@given(
    n=st.integers(0, 30),
    values=st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64), min_size=90, max_size=90),
    binary=st.booleans(),
)
def test_ply_round_trips_any_double(n: int, values: list[float], binary: bool) -> None:
    pts = np.array(values[: 3 * n], dtype=float).reshape(n, 3)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "c.ply"
        stripecal.write_ply(p, pts, {"view": np.arange(n, dtype=float)}, binary=binary)
        back = stripecal.read_ply(p)
        got = np.asarray(back["points"])
        assert got.shape == (n, 3)
        assert np.array_equal(got, pts, equal_nan=True)
        assert not [f for f in os.listdir(d) if ".tmp-" in f]


@FUZZ
@given(points=st.one_of(st.just(None), st.text(max_size=3), st.lists(st.lists(st.floats(), max_size=4), max_size=3)))
def test_write_ply_refuses_bad_arrays_cleanly(points: Any) -> None:
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "c.ply"
        p.write_bytes(b"old")
        try:
            stripecal.write_ply(p, points)
        except (stripecal.StripecalError, OSError, TypeError):
            assert p.read_bytes() == b"old", "a refused write changed the file"
        else:
            # written: complete and readable
            assert np.asarray(stripecal.read_ply(p)["points"]).shape == (len(points), 3)
        assert not [f for f in os.listdir(d) if ".tmp-" in f]


# ------------------------------------------------------------------ poses


def rotation(axis: list[float], angle: float) -> np.ndarray:
    a = np.asarray(axis, dtype=float)
    if np.linalg.norm(a) < 1e-6:
        return np.eye(3)
    return stripecal.rotvec_to_matrix(a / np.linalg.norm(a) * angle)


@FUZZ
@given(
    axis=st.lists(st.floats(-1, 1), min_size=3, max_size=3),
    angle=st.one_of(st.floats(-np.pi, np.pi), st.sampled_from([0.0, np.pi, np.pi / 2, -np.pi / 2])),
    t=st.lists(st.floats(-5000, 5000), min_size=3, max_size=3),
    convention=st.sampled_from(CONVENTIONS),
)
def test_pose_conventions_round_trip_as_matrices(
    axis: list[float], angle: float, t: list[float], convention: str
) -> None:
    m = np.eye(4)
    m[:3, :3] = rotation(axis, angle)
    m[:3, 3] = t
    values = stripecal.matrix_to_pose(m, convention)
    back = stripecal.pose_to_matrix(values, convention)
    assert np.allclose(back[:3, :3], m[:3, :3], atol=1e-9), (convention, values)
    assert np.allclose(back[:3, 3], m[:3, 3], atol=1e-9 * (1 + np.abs(m[:3, 3]).max()))


@FUZZ
@given(
    convention=st.one_of(st.sampled_from(CONVENTIONS), st.text(max_size=12), st.lists(st.sampled_from(["x_mm", "qw", "r11", "q1", ""]), max_size=8)),
    values=st.lists(
        st.one_of(st.floats(), st.sampled_from([1e308, -1e308, 7.2e166, 1e306, 0.0, 1.0])),
        max_size=13,
    ),
)
def test_pose_to_matrix_of_arbitrary_values(convention: Any, values: list[float]) -> None:
    out = call(stripecal.pose_to_matrix, values, convention)
    if out is not None:
        assert is_rigid(out), (convention, values, out)
        again = stripecal.matrix_to_pose(out, convention)
        assert finite(again)


@FUZZ
@given(m=st.lists(st.floats(), min_size=16, max_size=16), convention=st.sampled_from(CONVENTIONS))
def test_matrix_to_pose_of_arbitrary_matrices(m: list[float], convention: str) -> None:
    out = call(stripecal.matrix_to_pose, np.array(m).reshape(4, 4), convention)
    if out is not None:
        assert finite(out)


@pytest.mark.parametrize(
    "fn, args",
    [
        (stripecal.pose_to_matrix, ("abc", 3)),
        (stripecal.pose_to_matrix, ([1.0] * 7, None)),
        (stripecal.matrix_to_pose, (None, "kuka")),
        (stripecal.load_rig, (123,)),
        (stripecal.read_ply, (None,)),
        (stripecal.load_image, (b"\x00",)),
        (stripecal.load_dataset, (3.5,)),
    ],
)
def test_wrong_argument_types_raise_type_errors_or_typed_errors(fn: Callable[..., Any], args: tuple[Any, ...]) -> None:
    call(fn, *args, allow_type_error=True)


# ------------------------------------------------------------------ issue 39: refused, always


def _with_duplicate(doc: Any, path: list[int], again: Any) -> tuple[str, str]:
    """JSON text of ``doc`` with one key of one object (chosen by ``path``) written twice,
    the second time with ``again``; and that key's path (``board.rows``)."""
    objects: list[tuple[list[int], str, list[str]]] = []

    def walk(v: Any, idx: list[int], name: str) -> None:
        if isinstance(v, dict):
            if v:
                objects.append((idx, name, list(v)))
            for i, (k, x) in enumerate(v.items()):
                walk(x, idx + [i], f"{name}.{k}" if name else k)
        elif isinstance(v, list):
            for i, x in enumerate(v):
                walk(x, idx + [i], f"{name}[{i}]")

    walk(doc, [], "")
    at, name, keys = objects[path[0] % len(objects)]
    key = keys[path[1] % len(keys)]

    def dump(v: Any, idx: list[int] | None) -> str:
        if isinstance(v, dict):
            parts = []
            for i, (k, x) in enumerate(v.items()):
                deeper = idx[1:] if idx and idx[0] == i else None
                parts.append(f"{json.dumps(k)}: {dump(x, deeper)}")
                if idx == [] and k == key:
                    parts.append(f"{json.dumps(k)}: {json.dumps(again)}")
            return "{" + ", ".join(parts) + "}"
        if isinstance(v, list):
            return "[" + ", ".join(dump(x, idx[1:] if idx and idx[0] == i else None) for i, x in enumerate(v)) + "]"
        return json.dumps(v)

    return dump(doc, at), f"{name}.{key}" if name else key


@FUZZ
@given(path=st.lists(st.integers(0, 1000), min_size=2, max_size=2), again=json_leaf, which=st.integers(0, 1))
def test_a_repeated_json_key_is_refused_naming_it(path: list[int], again: Any, which: int, calibration_text: str) -> None:
    """serde_json kept the last of two equal keys silently (issue 39): now an error
    naming the key's path and line, whatever the second value is."""
    doc, reader = [(RIG, stripecal.load_rig), (json.loads(calibration_text), stripecal.load_calibration)][which]
    text, key = _with_duplicate(doc, path, again)
    with tempfile.TemporaryDirectory() as d:
        with pytest.raises(stripecal.FormatError) as e:
            reader(write(d, "doc.json", text.encode()))
    assert f"key `{key}` appears twice" in str(e.value) and ": line " in str(e.value)


@FUZZ
@given(n=st.integers(1, 6), j=st.integers(0, 100), at=st.integers(0, 100), convention=st.sampled_from(["joints"] + CONVENTIONS))
def test_a_repeated_row_is_refused_naming_both_lines(n: int, j: int, at: int, convention: str) -> None:
    """A row of views.csv / scan.csv repeated anywhere below itself counted one view twice
    (issue 39): refused, naming both lines."""
    rng = np.random.default_rng(n * 1000 + j)
    if convention == "joints":
        header = "q1,q2,q3,q4,q5,q6"
        values = [[float(x) for x in rng.uniform(-90, 90, 6)] for _ in range(n)]
    else:
        header = HEADERS[convention]
        values = [[float(x) for x in stripecal.matrix_to_pose(_pose(rng), convention)] for _ in range(n)]
    rows = [f"images/b{k}.png,images/l{k}.png," + ",".join(repr(x) for x in v) for k, v in enumerate(values)]
    j %= n
    at = j + 1 + at % (n - j)
    rows.insert(at, rows[j])
    with tempfile.TemporaryDirectory() as d:
        write(d, "rig.json", json.dumps(RIG).encode())
        write(d, "views.csv", ("board_image,laser_image," + header + "\n" + "\n".join(rows) + "\n").encode())
        with pytest.raises(stripecal.FormatError) as e:
            stripecal.load_dataset(d)
        scan_rows = [r.split(",", 1)[1] for r in rows]
        write(d, "scan/scan.csv", ("image," + header + "\n" + "\n".join(scan_rows) + "\n").encode())
        with pytest.raises(stripecal.FormatError) as e2:
            stripecal.load_scan(Path(d) / "scan")
    for err in (e.value, e2.value):
        m = str(err)
        assert f"line {at + 2}, column" in m and f"repeats line {j + 2} exactly" in m, m


def _pose(rng: np.random.Generator) -> np.ndarray:
    """A random rigid transform with a robot-sized translation (mm)."""
    w = rng.normal(size=3)
    th = np.linalg.norm(w)
    k = w / th
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    t = np.eye(4)
    t[:3, :3] = np.eye(3) + np.sin(th) * kx + (1 - np.cos(th)) * kx @ kx
    t[:3, 3] = rng.uniform(-1500, 1500, 3)
    return t


@FUZZ
@given(cut=st.floats(0.0, 0.999), size=st.sampled_from([(16, 12), (64, 48), (160, 90)]))
def test_a_truncated_jpeg_is_refused(cut: float, size: tuple[int, int]) -> None:
    """A JPEG cut anywhere decoded with its missing rows made up (issue 39): refused."""
    cv2 = pytest.importorskip("cv2")
    w, h = size
    img = ((np.arange(w * h).reshape(h, w) * 37) % 251).astype(np.uint8)
    ok, buf = cv2.imencode(".jpg", img)
    data = buf.tobytes()
    n = max(2, int(cut * (len(data) - 2)))
    with tempfile.TemporaryDirectory() as d:
        with pytest.raises(stripecal.FormatError):
            stripecal.load_image(write(d, "cut.jpg", data[:n]))
        # the whole file is read
        assert stripecal.load_image(write(d, "whole.jpg", data)).shape == (h, w)


def test_found_by_the_campaign_huge_rotation_vectors_are_refused() -> None:
    # a rotation vector whose norm overflows gave a NaN transform (issue 13)
    with pytest.raises(stripecal.InvalidInputError):
        stripecal.pose_to_matrix([0, 0, 0, 0, 7.2e166, 0], "rotvec")
    with pytest.raises(stripecal.InvalidInputError):
        stripecal.pose_to_matrix([1e306, 0, 0, 0, 0, 0], "ur")

