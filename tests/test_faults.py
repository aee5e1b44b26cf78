"""Issue 39, "Never a confident wrong answer, part two": the faults an adversarial campaign
found on the installed CLI, each through the command line (or the public API) on a
small twin rendered once for the module: the behaviour the issue asks for, and a
message that names the place (file, line, key, view) and the real reason.

The core's own tests cover the same faults without Python (crates/stripecal/tests/
fuzz_faults, reconstruct_errors.rs); interrupts (SIGTERM) are in test_scan_faults.py.
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path
from typing import Dict

import numpy as np
import pytest

import stripecal
from stripecal.cli import main

REALDATA = Path(__file__).resolve().parents[1].parent / "shared" / "realdata"

SMALL_CAMERA = {"width": 384, "height": 288, "fu": 635.825, "fv": 661.26, "u0": 172.82, "v0": 131.05}


@pytest.fixture(scope="module")
def twin(tmp_path_factory: pytest.TempPathFactory) -> Dict[str, Path]:
    """A half-size twin: 4 calibration views, a 4-frame scan, and its true calibration."""
    out = tmp_path_factory.mktemp("faults39")
    rc = main(["simulate", str(out / "sim"), "--seed", "5", "--poses", "4", "--scan-frames", "4",
               "--scan-step", "3", "--set", "camera=" + json.dumps(SMALL_CAMERA)])
    assert rc == 0
    truth = stripecal.load_truth(out / "sim" / "calib" / "truth.json")
    cal = stripecal.Calibration(truth.camera, truth.laser_plane, truth.hand_cam, truth.base_board, robot=truth.robot)
    stripecal.save_calibration(out / "calibration.json", cal)
    return {"root": out, "calib": out / "sim" / "calib", "scan": out / "sim" / "scan", "cal": out / "calibration.json"}


def copy(twin: Dict[str, Path], tmp_path: Path) -> Path:
    data = tmp_path / "calib"
    shutil.copytree(twin["calib"], data)
    return data


def views(data: Path) -> list[list[str]]:
    return [r.split(",") for r in (data / "views.csv").read_text().splitlines()[1:]]


def run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    capsys.readouterr()
    rc = main(list(args))
    out = capsys.readouterr()
    return rc, out.out, out.err


# --- fault 4: --from a calibration of another image size ---------------------------------


def test_from_a_calibration_of_another_size_is_refused(twin, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    doc = json.loads(Path(twin["cal"]).read_text())
    doc["camera"]["width"], doc["camera"]["height"] = 640, 480
    other = tmp_path / "cal640.json"
    other.write_text(json.dumps(doc))
    out = tmp_path / "out.json"
    for flags in (["--fix", "camera"], ["--laser-only"], []):
        rc, _, err = run(capsys, "calibrate", str(twin["calib"]), "--from", str(other), *flags, "-o", str(out))
        assert rc == 1, flags
        assert "is of a 640 x 480 camera" in err and "this dataset's images are 384 x 288" in err, (flags, err)
        assert "laser" not in err.split("error:")[1].split("(")[0], err  # not a laser-plane error
        assert not out.exists()


# --- fault 6: a truncated JPEG frame -----------------------------------------------------


def test_truncated_jpeg_frame_is_refused_or_skipped(twin, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    cv2 = pytest.importorskip("cv2")
    scan = tmp_path / "scan"
    shutil.copytree(twin["scan"], scan)
    rows = (scan / "scan.csv").read_text().splitlines()
    cells = rows[2].split(",")
    name = Path(cells[0])
    jpg = name.with_suffix(".jpg")
    ok, buf = cv2.imencode(".jpg", stripecal.load_image(scan / name))
    data = buf.tobytes()
    (scan / jpg).write_bytes(data[: len(data) * 2 // 3])
    cells[0] = jpg.as_posix()
    rows[2] = ",".join(cells)
    (scan / "scan.csv").write_text("\n".join(rows) + "\n")
    ply = tmp_path / "cloud.ply"
    rc, _, err = run(capsys, "reconstruct", str(twin["cal"]), str(scan), "-o", str(ply))
    assert rc == 1 and "frame 1 (scan.csv line 3)" in err and "truncated JPEG" in err, err
    assert not ply.exists()
    rc, out, _ = run(capsys, "reconstruct", str(twin["cal"]), str(scan), "-o", str(ply), "--on-bad-image", "skip")
    assert rc == 0 and "(1 skipped)" in out and "truncated JPEG" in out, out
    assert b"comment skipped_frames 1" in ply.read_bytes()


# --- fault 7: a PNG whose compressed data is damaged, CRCs intact ------------------------


def damage_png(src: bytes, frac: float) -> bytes:
    """``src`` with one byte of its compressed image data changed at ``frac`` of the first
    IDAT chunk and that chunk's CRC recomputed."""
    b = bytearray(src)
    pos = 8
    while pos + 12 <= len(b):
        n = struct.unpack(">I", b[pos:pos + 4])[0]
        if b[pos + 4:pos + 8] == b"IDAT":
            at = pos + 8 + max(2, int(frac * n))
            b[at] ^= 0x24
            b[pos + 8 + n:pos + 12 + n] = struct.pack(">I", zlib.crc32(bytes(b[pos + 4:pos + 8 + n])) & 0xFFFFFFFF)
            return bytes(b)
        pos += 12 + n
    raise AssertionError("no IDAT")


def test_damaged_png_is_named_as_damaged(twin, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    data = copy(twin, tmp_path)
    board = views(data)[1][0]
    clean = (data / board).read_bytes()
    for frac in (0.02, 0.3, 0.6):
        (data / board).write_bytes(damage_png(clean, frac))
        rc, _, err = run(capsys, "calibrate", str(data), "-o", str(tmp_path / "c.json"))
        assert rc == 1 and board in err and "damaged PNG" in err, (frac, err)
        assert "board not found" not in err


# --- fault 9: detect from the folder above -----------------------------------------------


def test_detect_a_relative_dataset_from_the_folder_above(twin, capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.chdir(twin["calib"].parent)
    rc, out, err = run(capsys, "detect", "calib")
    assert rc == 0, err
    assert "4 of 4 images detected" in out


@pytest.mark.skipif(not (REALDATA / "rosi_10x10").is_dir(), reason="../shared/realdata not present")
def test_detect_realdata_from_the_folder_above(capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.chdir(REALDATA.parent)
    rc, out, err = run(capsys, "detect", "realdata/rosi_10x10")
    assert rc == 0 and "No such file" not in err, err


# --- fault 10: a board declared far larger than the print --------------------------------


@pytest.mark.parametrize("size", [20, 1000])
def test_a_board_declared_far_larger_is_refused(twin, tmp_path, capsys, size) -> None:  # type: ignore[no-untyped-def]
    data = copy(twin, tmp_path)
    rig = json.loads((data / "rig.json").read_text())
    rig["board"]["rows"] = rig["board"]["cols"] = size
    (data / "rig.json").write_text(json.dumps(rig))
    with pytest.raises(stripecal.DetectionError, match=f"the board \\({size} x {size} circles\\) was found in 0 of 4"):
        stripecal.calibrate(data)
    rc, _, err = run(capsys, "calibrate", str(data), "-o", str(tmp_path / "c.json"))
    assert rc == 1 and "the grid ends inside the image" in err


# --- fault 11: a repeated row ------------------------------------------------------------


def test_a_repeated_row_is_refused_naming_both_lines(twin, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    data = copy(twin, tmp_path)
    text = (data / "views.csv").read_text()
    (data / "views.csv").write_text(text + text.splitlines()[2] + "\n")
    rc, _, err = run(capsys, "calibrate", str(data), "-o", str(tmp_path / "c.json"))
    assert rc == 1
    assert "views.csv: line 6, column board_image: repeats line 3 exactly" in err, err


# --- an image's size from its header, before decoding -----------------------------------


def huge_png(w: int, h: int) -> bytes:
    """A valid all-black 8-bit gray PNG of ``w x h`` pixels (under 1 MB for 30000 x 30000):
    a block of zero rows deflated once (full flushes make blocks independent), repeated,
    with the Adler-32 of the zero bytes."""
    def chunk(t: bytes, d: bytes) -> bytes:
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)

    rows = 1000
    assert h % rows == 0
    block = b"\0" * ((w + 1) * rows)
    c = zlib.compressobj(9)
    first = c.compress(block) + c.flush(zlib.Z_FULL_FLUSH)
    again = c.compress(block) + c.flush(zlib.Z_FULL_FLUSH)
    n = (w + 1) * h
    data = first + again * (h // rows - 1) + b"\x03\x00" + struct.pack(">I", ((n % 65521) << 16) | 1)
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", data) + chunk(b"IEND", b"")


# Runs the CLI, then prints the process's peak resident memory (VmHWM, kB: the process's
# own since exec; a child's ru_maxrss would count the forking parent's pages too).
PEAK = ("import sys, stripecal.cli; rc = stripecal.cli.main(sys.argv[1:]); "
        "print(next(l for l in open('/proc/self/status') if l.startswith('VmHWM'))); sys.exit(rc)")


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="/proc (peak memory)")
def test_a_huge_image_is_refused_from_its_header_with_little_memory(twin, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A complete 30000 x 30000 PNG (decoded, 900 MB) where a 384 x 288 board image should
    be: refused naming both sizes, the whole command's peak memory under 100 MB."""
    small = huge_png(1000, 2000)
    assert stripecal.load_image(write_to(tmp_path / "check.png", small)).shape == (2000, 1000)
    data = copy(twin, tmp_path)
    board = views(data)[1][0]
    (data / board).write_bytes(huge_png(30000, 30000))
    proc = subprocess.run([sys.executable, "-c", PEAK, "calibrate", str(data), "-o", str(tmp_path / "c.json")],
                          capture_output=True, text=True)
    assert proc.returncode == 1, proc.stderr
    err = proc.stderr
    assert "view 1 (views.csv line 3)" in err and "is 30000 x 30000, rig.json says 384 x 288" in err, err
    peak_mb = int(proc.stdout.split("VmHWM:")[1].split()[0]) / 1024
    assert peak_mb < 100, f"peak memory {peak_mb:.0f} MB"
    # detect reads the size from the header too
    with pytest.raises(stripecal.FormatError, match="30000 x 30000 pixels, expected 384 x 288"):
        stripecal.load_image(data / board, size=(384, 288))


def write_to(p: Path, data: bytes) -> Path:
    p.write_bytes(data)
    return p


# --- messages that name the place and the reason -----------------------------------------


def flange_views(data: Path, scale: float) -> None:
    """Rewrites the dataset's views.csv with flange poses under x_m,y_m,z_m (the joints'
    forward kinematics, translations times ``scale``: 0.001 gives metres, 1 millimetres)."""
    ds = stripecal.load_dataset(data)
    poses = ds.base_hand()
    rows = ["board_image,laser_image,x_m,y_m,z_m,qw,qx,qy,qz"]
    for v, t in zip(views(data), poses):
        vals = stripecal.matrix_to_pose(t, ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"])
        vals[:3] *= scale
        rows.append(",".join(v[:2] + [repr(float(x)) for x in vals]))
    (data / "views.csv").write_text("\n".join(rows) + "\n")
    rig = json.loads((data / "rig.json").read_text())
    del rig["robot"]
    (data / "rig.json").write_text(json.dumps(rig))


def test_millimetres_under_x_m_are_named(twin, tmp_path) -> None:  # type: ignore[no-untyped-def]
    data = copy(twin, tmp_path)
    flange_views(data, 1.0)
    with pytest.raises(stripecal.FormatError) as e:
        stripecal.load_dataset(data)
    m = str(e.value)
    assert "views.csv: line 2, columns x_m, y_m, z_m" in m and "these numbers look like millimetres" in m, m


def test_a_huge_cell_names_its_column_in_few_digits(twin, tmp_path) -> None:  # type: ignore[no-untyped-def]
    data = copy(twin, tmp_path)
    flange_views(data, 0.001)
    text = (data / "views.csv").read_text().splitlines()
    for col, name in [(2, "x_m"), (4, "z_m")]:
        cells = text[2].split(",")
        cells[col] = "1e308"
        (data / "views.csv").write_text("\n".join(text[:2] + [",".join(cells)] + text[3:]) + "\n")
        with pytest.raises(stripecal.FormatError) as e:
            stripecal.load_dataset(data)
        m = str(e.value)
        assert f"line 3, column {name}: {name} = 1e308 is too large" in m, m
        assert "0" * 30 not in m


@pytest.mark.parametrize("pitch", [1e-9, 2e5, 1e300])
def test_an_extreme_pitch_names_the_key(twin, tmp_path, pitch) -> None:  # type: ignore[no-untyped-def]
    data = copy(twin, tmp_path)
    rig = json.loads((data / "rig.json").read_text())
    rig["board"]["pitch_mm"] = pitch
    (data / "rig.json").write_text(json.dumps(rig))
    with pytest.raises(stripecal.FormatError, match="rig.json: board.pitch_mm: .* is not a board's spacing"):
        stripecal.load_dataset(data)


def test_a_duplicated_json_key_is_an_error_naming_it(twin, tmp_path) -> None:  # type: ignore[no-untyped-def]
    data = copy(twin, tmp_path)
    text = (data / "rig.json").read_text()
    (data / "rig.json").write_text(text.replace('"pitch_mm":', '"pitch_mm": 4.0, "pitch_mm":', 1))
    with pytest.raises(stripecal.FormatError, match="key `board.pitch_mm` appears twice"):
        stripecal.load_dataset(data)


@pytest.mark.skipif(os.name != "posix", reason="FIFOs and /dev/zero")
@pytest.mark.parametrize("kind", ["folder", "fifo", "dev-zero", "symlink-loop"])
def test_a_special_file_where_an_image_should_be(twin, tmp_path, kind) -> None:  # type: ignore[no-untyped-def]
    data = copy(twin, tmp_path)
    board = data / views(data)[0][0]
    board.unlink()
    says = {"folder": "is a folder, not a file", "fifo": "is a FIFO (named pipe), not a regular file",
            "dev-zero": "is a character device", "symlink-loop": "symbolic link that cannot be followed"}[kind]
    if kind == "folder":
        board.mkdir()
    elif kind == "fifo":
        os.mkfifo(board)
    elif kind == "dev-zero":
        board.symlink_to("/dev/zero")
    else:
        board.symlink_to(board.name)
    with pytest.raises(stripecal.FormatError) as e:
        stripecal.load_dataset(data)
    assert "views.csv: line 2: image " in str(e.value) and says in str(e.value), str(e.value)
    with pytest.raises(OSError) as e2:
        stripecal.load_image(board)
    assert says in str(e2.value), str(e2.value)


def test_laser_images_without_a_line_are_named(twin, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    data = copy(twin, tmp_path)
    for v in views(data):
        stripecal.save_image(data / v[1], np.full((288, 384), 9, np.uint8))
    rc, out, _ = run(capsys, "calibrate", str(data), "-o", str(tmp_path / "c.json"), "--no-leave-one-out")
    assert rc == 0
    assert "laser plane: not estimated (no laser line on the board in any of the 4 laser images" in out, out
    assert "no laser line found in the laser image of views 0, 1, 2 and 3" in out, out
    assert "(no laser images)" not in out


# --- sphere.json: the fit's sigmas named as what they are --------------------------------


def test_sphere_json_names_its_fit_only_sigmas(twin, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(1)
    d = rng.normal(size=(3000, 3))
    pts = 22.4 * d / np.linalg.norm(d, axis=1)[:, None] + [100.0, 20.0, 300.0] + rng.normal(0, 0.01, (3000, 3))
    cloud = tmp_path / "ball.ply"
    stripecal.write_ply(cloud, pts)
    out = tmp_path / "sphere.json"
    rc, text, _ = run(capsys, "fit-sphere", str(cloud), "-o", str(out))
    assert rc == 0 and "random part only" in text and "stripecal measure" in text
    doc = json.loads(out.read_text())
    assert "fit_diameter_sigma_mm" in doc and "fit_center_sigma_mm" in doc
    assert "diameter_sigma_mm" not in doc and "center_sigma_mm" not in doc
    assert "stripecal measure" in doc["sigma_note"]
    fit = stripecal.load_sphere_fit(out)
    assert fit.fit_diameter_sigma_mm == doc["fit_diameter_sigma_mm"] == fit.diameter_sigma_mm
    # an older file, with the former names, reads as before
    old = dict(doc)
    old["diameter_sigma_mm"] = old.pop("fit_diameter_sigma_mm")
    old["center_sigma_mm"] = old.pop("fit_center_sigma_mm")
    (tmp_path / "old.json").write_text(json.dumps(old))
    before = stripecal.load_sphere_fit(tmp_path / "old.json")
    assert before.fit_diameter_sigma_mm == doc["fit_diameter_sigma_mm"]
    assert np.array_equal(before.fit_center_sigma_mm, doc["fit_center_sigma_mm"])
