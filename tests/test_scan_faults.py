"""Faults in the middle of a scan run: bad images (truncated, a truncated JPEG, a PNG
with damaged compressed data, random bytes, missing, wrong size, another bit depth) with
``on_bad_image`` stop / skip, and interrupted runs (SIGINT during ``stripecal
reconstruct`` and ``stripecal calibrate``, SIGTERM during ``reconstruct``, while its
output is written and during ``simulate``, SIGKILL during ``reconstruct``): the output
is complete or absent, an earlier file is left as it was, nothing is left beside it.

One small twin (3 calibration views, a 6-frame ball scan) is rendered for the module.
Long runs for the signal tests come from scan.csv / views.csv files that repeat the
same few images many times (under other names: hard links), so nothing more is
rendered. No timing assertions: a signal is sent once the run has visibly started (its
progress bar on a pseudo-terminal, CPU time spent, a temporary file that appeared), and
what is checked is the outcome."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np
import pytest

import stripecal
from stripecal.cli import main

BAD = 2  # the frame spoiled: scan.csv line BAD + 2
FRAMES = 6


@pytest.fixture(scope="module")
def twin(tmp_path_factory: pytest.TempPathFactory) -> Dict[str, Path]:
    out = tmp_path_factory.mktemp("faults")
    rc = main(["simulate", str(out / "sim"), "--seed", "7", "--poses", "3",
               "--scan-frames", str(FRAMES), "--scan-step", "3"])
    assert rc == 0
    scan = out / "sim" / "scan"
    truth = stripecal.load_truth(scan / "truth.json")
    cal = stripecal.Calibration(truth.camera, truth.laser_plane, truth.hand_cam, truth.base_board, robot=truth.robot)
    cal_path = out / "calibration.json"
    stripecal.save_calibration(cal_path, cal)
    return {"cal": cal_path, "scan": scan, "calib": out / "sim" / "calib", "root": out}


@pytest.fixture(scope="module")
def clean(twin: Dict[str, Path]) -> stripecal.Cloud:
    cloud = stripecal.reconstruct_scan(stripecal.load_calibration(twin["cal"]), twin["scan"])
    assert cloud.skipped_frames == []
    assert set(np.unique(cloud.frame)) == set(range(FRAMES))
    return cloud


def image_name(scan: Path, k: int) -> str:
    rows = (scan / "scan.csv").read_text().splitlines()
    return rows[k + 1].split(",")[0]


def truncate(p: Path) -> None:
    b = p.read_bytes()
    p.write_bytes(b[: len(b) // 2])


def random_bytes(p: Path) -> None:
    p.write_bytes(np.random.default_rng(3).integers(0, 256, 20000, dtype=np.uint8).tobytes())


def remove(p: Path) -> None:
    p.unlink()


def wrong_size(p: Path) -> None:
    stripecal.save_image(p, np.zeros((100, 120), np.uint8))


def sixteen_bit(p: Path) -> None:
    a = stripecal.load_image(p)
    assert a.dtype == np.uint8
    stripecal.save_image(p, a.astype(np.uint16) * 257)


def truncated_jpeg(p: Path) -> None:
    """The frame as a JPEG cut inside its image data (decoded silently before, its
    missing rows made up: issue 39, fault 6)."""
    cv2 = pytest.importorskip("cv2")
    ok, buf = cv2.imencode(".jpg", stripecal.load_image(p))
    data = buf.tobytes()
    p.write_bytes(data[: len(data) * 2 // 3])


def damaged_png(p: Path) -> None:
    """One byte of the compressed image data changed, the chunk's CRC recomputed (issue 39,
    fault 7): only the zlib checksum tells."""
    import struct
    import zlib

    b = bytearray(p.read_bytes())
    pos = 8
    while pos + 12 <= len(b):
        n = struct.unpack(">I", b[pos:pos + 4])[0]
        if b[pos + 4:pos + 8] == b"IDAT":
            b[pos + 8 + n // 50] ^= 0x24
            b[pos + 8 + n:pos + 12 + n] = struct.pack(">I", zlib.crc32(bytes(b[pos + 4:pos + 8 + n])) & 0xFFFFFFFF)
            break
        pos += 12 + n
    p.write_bytes(bytes(b))


# (name, spoil, what the reason says)
KINDS: List[Tuple[str, Callable[[Path], None], str]] = [
    ("truncated-jpeg", truncated_jpeg, "truncated JPEG"),
    ("damaged-png", damaged_png, "damaged PNG"),
    ("truncated", truncate, "cannot be decoded"),
    ("random-bytes", random_bytes, "cannot be decoded"),
    ("missing", remove, "does not exist"),
    ("wrong-size", wrong_size, "is 120 x 100 pixels, the calibrated camera is 768 x 576"),
    ("16-bit", sixteen_bit, f"is 16-bit, but {FRAMES - 1} of the scan's {FRAMES} readable frames are 8-bit"),
]


def no_temp_files(folder: Path) -> bool:
    return not [p.name for p in folder.iterdir() if ".tmp" in p.name]


@pytest.mark.parametrize("kind,spoil,reason", KINDS, ids=[k[0] for k in KINDS])
def test_bad_image_in_the_middle(twin, clean, tmp_path, capsys, kind, spoil, reason) -> None:  # type: ignore[no-untyped-def]
    scan = tmp_path / "scan"
    shutil.copytree(twin["scan"], scan)
    name = image_name(scan, BAD)
    spoil(scan / name)
    cal = stripecal.load_calibration(twin["cal"])

    # stop (the default): a typed error naming the frame, its line, the file, the fault
    with pytest.raises(stripecal.BadImageError) as ei:
        stripecal.reconstruct_scan(cal, scan)
    e = ei.value
    assert isinstance(e, stripecal.FormatError)
    assert (e.frame, e.line) == (BAD, BAD + 2)
    assert Path(e.path) == scan / name and reason in e.reason
    assert str(e).startswith(f"frame {BAD} (scan.csv line {BAD + 2}): image {scan / name}: ")

    # skip: every other frame's points, exactly; the frame listed with the same facts
    cloud = stripecal.reconstruct_scan(cal, scan, on_bad_image="skip")
    keep = clean.frame != BAD
    assert np.array_equal(cloud.points, clean.points[keep])
    assert np.array_equal(cloud.frame, clean.frame[keep])
    assert cloud.skipped_frames == [{"frame": BAD, "line": BAD + 2, "path": str(scan / name), "reason": e.reason}]
    assert "skipped_frames=1" in repr(cloud)

    # the CLI, stop: exit 1, the message names frame and file, no output file
    ply = tmp_path / "out" / "cloud.ply"
    ply.parent.mkdir()
    capsys.readouterr()
    assert main(["reconstruct", str(twin["cal"]), str(scan), "-o", str(ply)]) == 1
    err = capsys.readouterr().err
    assert f"frame {BAD} (scan.csv line {BAD + 2})" in err and name in err and reason in err
    assert not ply.exists() and no_temp_files(ply.parent)
    # ... and an earlier file at the path is left as it was
    ply.write_bytes(b"an earlier cloud")
    assert main(["reconstruct", str(twin["cal"]), str(scan), "-o", str(ply), "--on-bad-image", "stop"]) == 1
    assert ply.read_bytes() == b"an earlier cloud" and no_temp_files(ply.parent)
    capsys.readouterr()

    # the CLI, skip: exit 0, the skipped frame printed and counted in the PLY header
    assert main(["reconstruct", str(twin["cal"]), str(scan), "-o", str(ply), "--on-bad-image", "skip"]) == 0
    out = capsys.readouterr().out
    assert f"from {FRAMES - 1} of {FRAMES} frames (1 skipped)" in out
    assert "skipped 1 frame with a bad image" in out
    assert f"frame {BAD} (scan.csv line {BAD + 2}): image {scan / name}: {e.reason}" in out
    data = ply.read_bytes()
    header = data[: data.index(b"end_header\n")].decode()
    assert "\ncomment skipped_frames 1\n" in header
    assert f"\ncomment skipped frame {BAD} (scan.csv line {BAD + 2}): image " in header
    assert np.array_equal(stripecal.read_ply(ply)["points"], cloud.points)
    assert no_temp_files(ply.parent)


def test_every_frame_bad_writes_nothing(twin, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    scan = tmp_path / "scan"
    shutil.copytree(twin["scan"], scan)
    for k in range(FRAMES):
        (scan / image_name(scan, k)).write_bytes(b"")
    ply = tmp_path / "cloud.ply"
    assert main(["reconstruct", str(twin["cal"]), str(scan), "-o", str(ply), "--on-bad-image", "skip"]) == 1
    assert f"{FRAMES} of {FRAMES} frames skipped as bad images" in capsys.readouterr().err
    assert not ply.exists()


def test_clean_scan_header_says_none_skipped(twin, tmp_path) -> None:  # type: ignore[no-untyped-def]
    ply = tmp_path / "cloud.ply"
    assert main(["reconstruct", str(twin["cal"]), str(twin["scan"]), "-o", str(ply), "--ascii"]) == 0
    assert b"\ncomment skipped_frames 0\nelement vertex" in ply.read_bytes()


def test_bad_on_bad_image_value(twin) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(stripecal.InvalidInputError, match="on_bad_image"):
        stripecal.reconstruct_scan(stripecal.load_calibration(twin["cal"]), twin["scan"], on_bad_image="ignore")


# --- interrupts ---------------------------------------------------------------------


def repeated_rows(folder: Path, table: str, times: int) -> None:
    """Rewrites ``folder/table`` (scan.csv or views.csv) with its rows repeated ``times``
    times, each repeat naming hard links to the images under new names: a long run
    without rendering more, and without naming one file on two rows (refused: it would
    count one image twice)."""
    rows = (folder / table).read_text().splitlines()
    ncols = 2 if table == "views.csv" else 1
    out = [rows[0]]
    for k in range(times):
        for row in rows[1:]:
            cells = row.split(",")
            for c in range(ncols):
                if cells[c] and k > 0:
                    name = Path(cells[c])
                    link = name.with_name(f"{name.stem}_r{k}{name.suffix}")
                    if not (folder / link).exists():
                        os.link(folder / name, folder / link)
                    cells[c] = link.as_posix()
            out.append(",".join(cells))
    (folder / table).write_text("\n".join(out) + "\n")


@pytest.fixture(scope="module")
def long_scan(twin: Dict[str, Path]) -> Path:
    """The twin's scan with its 6 frames 400 times over (2400 frames, hard links)."""
    scan = twin["root"] / "long_scan"
    shutil.copytree(twin["scan"], scan)
    repeated_rows(scan, "scan.csv", 400)
    return scan


def test_progress_exception_stops_the_run(twin, long_scan) -> None:  # type: ignore[no-untyped-def]
    """An exception of the progress callback (here the KeyboardInterrupt of a SIGINT the
    callback sends itself) stops the run at that chunk and propagates."""
    if not hasattr(signal, "SIGINT"):
        pytest.skip("no SIGINT")
    cal = stripecal.load_calibration(twin["cal"])
    calls: List[int] = []

    def progress(done: int, total: int, points: int) -> None:
        calls.append(done)
        if done > 0:
            os.kill(os.getpid(), signal.SIGINT)

    # Python's own handler, even when this test runs with SIGINT ignored
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            stripecal.reconstruct_scan(cal, long_scan, progress=progress)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert len(calls) == 2 and calls[1] < 400 * FRAMES, calls

    class Stop(Exception):
        pass

    def stop(done: int, total: int, points: int) -> None:
        raise Stop

    with pytest.raises(Stop):
        stripecal.reconstruct_scan(cal, long_scan, progress=stop)


posix_only = pytest.mark.skipif(os.name != "posix" or not Path("/proc/self/stat").exists(),
                                reason="signals, pseudo-terminals and /proc")


def child_env() -> Dict[str, str]:
    env = dict(os.environ)
    env["PYTHONUNBUFFERED"] = "1"
    return env


def default_sigint() -> None:
    """In the child before exec: SIGINT at its default, so that Python installs its
    KeyboardInterrupt handler even when this test runs with SIGINT ignored (a background
    job of a non-interactive shell, nohup): ignored signals stay ignored across exec."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def run_on_pty(args: List[str], cwd: Path, ready: Callable[[str], bool], sig: int) -> Tuple[int, str, str]:
    """Runs ``python -m stripecal ARGS`` with stderr on a pseudo-terminal (so that the
    progress bar is drawn), sends `sig` once `ready(stderr so far)`, and returns
    (exit status, stdout, stderr)."""
    import pty
    import select

    master, slave = pty.openpty()
    proc = subprocess.Popen([sys.executable, "-m", "stripecal", *args], cwd=cwd, env=child_env(),
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=slave,
                            preexec_fn=default_sigint)
    os.close(slave)
    buf = b""
    sent = False
    deadline = time.monotonic() + 300  # a guard against hanging, not a timing assertion
    try:
        while time.monotonic() < deadline:
            r, _, _ = select.select([master], [], [], 0.2)
            if not r:
                if proc.poll() is not None:
                    break
                continue
            try:
                chunk = os.read(master, 65536)
            except OSError:  # EIO: the child has closed the terminal
                break
            if not chunk:
                break
            buf += chunk
            if not sent and ready(buf.decode(errors="replace")):
                proc.send_signal(sig)
                sent = True
        else:
            proc.kill()
            pytest.fail("the child did not finish")
        rc = proc.wait(timeout=300)
    finally:
        os.close(master)
    assert sent, f"never ready: {buf.decode(errors='replace')}"
    assert proc.stdout is not None
    return rc, proc.stdout.read().decode(), buf.decode(errors="replace")


def frames_done(text: str) -> List[int]:
    return [int(m.group(1)) for m in re.finditer(r"(\d+)/(\d+)", text)]


def reconstructing(text: str) -> bool:
    """The progress bar shows at least one chunk of frames done."""
    return "reconstructing" in text and any(d > 0 for d in frames_done(text))


@posix_only
def test_sigint_during_reconstruct_writes_nothing(twin, long_scan, tmp_path) -> None:  # type: ignore[no-untyped-def]
    total = 400 * FRAMES
    for earlier in [None, b"an earlier cloud\n"]:
        out = tmp_path / ("fresh" if earlier is None else "earlier")
        out.mkdir()
        ply = out / "cloud.ply"
        if earlier is not None:
            ply.write_bytes(earlier)
        rc, stdout, stderr = run_on_pty(["reconstruct", str(twin["cal"]), str(long_scan), "-o", str(ply)],
                                        tmp_path, reconstructing, signal.SIGINT)
        assert rc == 130, (stdout, stderr)
        assert "stripecal reconstruct: interrupted; nothing written" in stderr
        assert "Traceback" not in stderr and "wrote" not in stdout
        # it stopped between chunks, long before the end of the scan
        assert max(frames_done(stderr)) < total, stderr[-300:]
        assert (ply.read_bytes() == earlier) if earlier is not None else not ply.exists()
        assert sorted(p.name for p in out.iterdir()) == ([] if earlier is None else ["cloud.ply"])


@posix_only
def test_sigkill_during_reconstruct_leaves_the_earlier_cloud(twin, long_scan, tmp_path) -> None:  # type: ignore[no-untyped-def]
    ply = tmp_path / "cloud.ply"
    assert main(["reconstruct", str(twin["cal"]), str(twin["scan"]), "-o", str(ply)]) == 0
    earlier = ply.read_bytes()
    rc, _, stderr = run_on_pty(["reconstruct", str(twin["cal"]), str(long_scan), "-o", str(ply)],
                               tmp_path, reconstructing, signal.SIGKILL)
    assert rc == -signal.SIGKILL, stderr
    assert max(frames_done(stderr)) < 400 * FRAMES
    assert ply.read_bytes() == earlier
    assert no_temp_files(tmp_path)


@posix_only
def test_sigterm_during_reconstruct_writes_nothing(twin, long_scan, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """SIGTERM (a service manager's stop) takes Ctrl-C's way out: stopped between chunks,
    nothing written, exit 143 (issue 39, fault 8)."""
    out = tmp_path / "out"
    out.mkdir()
    ply = out / "cloud.ply"
    rc, stdout, stderr = run_on_pty(["reconstruct", str(twin["cal"]), str(long_scan), "-o", str(ply)],
                                    tmp_path, reconstructing, signal.SIGTERM)
    assert rc == 143, (stdout, stderr)
    assert "stripecal reconstruct: terminated (SIGTERM); nothing written" in stderr
    assert "Traceback" not in stderr and "wrote" not in stdout
    assert max(frames_done(stderr)) < 400 * FRAMES
    assert list(out.iterdir()) == []


def hidden(folder: Path) -> List[str]:
    """What a writer left beside its targets: hidden temporaries and staging folders."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


@posix_only
def test_sigterm_while_the_cloud_is_written_leaves_no_temporary(twin, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """SIGTERM once the cloud's temporary file exists (the write has begun): the write
    completes, the command exits 143 saying so, and nothing is left beside the target;
    it used to die there and leave the hidden ``.cloud.ply.tmp-PID-0`` forever (issue 39,
    fault 8). The signal is sent when the temporary file appears, not after a delay; a
    write too quick to be caught is retried with a larger cloud."""
    scan = tmp_path / "scan"
    shutil.copytree(twin["scan"], scan)
    repeated_rows(scan, "scan.csv", 30)
    caught = False
    for attempt in range(3):
        out = tmp_path / f"out{attempt}"
        out.mkdir()
        ply = out / "cloud.ply"
        proc = subprocess.Popen([sys.executable, "-m", "stripecal", "reconstruct", str(twin["cal"]), str(scan),
                                 "-o", str(ply), "--ascii"],
                                cwd=tmp_path, env=child_env(), stdin=subprocess.DEVNULL,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        while proc.poll() is None and not [p for p in out.iterdir() if ".tmp-" in p.name]:
            pass
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            caught = True
        stdout, stderr = proc.communicate(timeout=600)
        assert hidden(out) == [], (hidden(out), stderr)
        if caught:
            assert proc.returncode == 143, (stdout, stderr)
            assert "terminated (SIGTERM) after completing its output" in stderr
            assert len(stripecal.read_ply(ply)["points"]) > 0
            break
        assert proc.returncode == 0, (stdout, stderr)
        repeated_rows(scan, "scan.csv", 2)
    if not caught:
        pytest.skip("the cloud was always written before the signal could be sent")


@posix_only
def test_sigterm_while_simulate_writes_leaves_no_staging_folder(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """SIGTERM once the twin's staging folder ``.calib.partial-PID`` exists: nothing is
    left beside the output (it used to stay forever, issue 39, fault 8); the folder is
    said to be possibly incomplete, exit 143."""
    out = tmp_path / "sim"
    out.mkdir()
    camera = '{"width": 192, "height": 144, "fu": 317.9, "fv": 330.6, "u0": 86.4, "v0": 65.5}'
    proc = subprocess.Popen([sys.executable, "-m", "stripecal", "simulate", str(out), "--poses", "3",
                             "--scan-frames", "3", "--set", f"camera={camera}"],
                            cwd=tmp_path, env=child_env(), stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    while proc.poll() is None and not hidden(out):
        pass
    assert proc.poll() is None, "the twin was written before its staging folder was seen"
    proc.send_signal(signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 143, (stdout, stderr)
    assert f"stripecal simulate: terminated (SIGTERM); {out} may be incomplete" in stderr
    assert "Traceback" not in stderr
    assert hidden(out) == []


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process so far (Linux /proc)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@posix_only
def test_sigint_during_calibrate_writes_nothing(twin, tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The interrupt stops the calibration at the core's next step (the binding polls
    for signals while the core runs and sets its cancellation flag), and nothing is
    written. The dataset has its 3 views 20 times over (hard links to the images), so
    the run takes several times the CPU time of starting Python and importing stripecal
    (~0.15 s); the signal is sent once 0.8 s of CPU time is spent, i.e. inside the
    calibration."""
    data = tmp_path / "calib"
    shutil.copytree(twin["calib"], data)
    repeated_rows(data, "views.csv", 20)
    for earlier in [None, b'{"an": "earlier calibration"}\n']:
        out = tmp_path / ("fresh" if earlier is None else "earlier")
        out.mkdir()
        target = out / "calibration.json"
        if earlier is not None:
            target.write_bytes(earlier)
        proc = subprocess.Popen([sys.executable, "-m", "stripecal", "calibrate", str(data), "-o", str(target),
                                 "--no-leave-one-out"],
                                cwd=tmp_path, env=child_env(), stdin=subprocess.DEVNULL,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                preexec_fn=default_sigint)
        while proc.poll() is None and cpu_seconds(proc.pid) < 0.8:
            time.sleep(0.02)
        assert proc.poll() is None, "the calibration ended before it could be interrupted: give it more views"
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=600)
        assert proc.returncode == 130, (stdout, stderr)
        assert "stripecal calibrate: interrupted; nothing written" in stderr
        assert "Traceback" not in stderr and "wrote" not in stdout
        assert (target.read_bytes() == earlier) if earlier is not None else not target.exists()
        assert sorted(p.name for p in out.iterdir()) == ([] if earlier is None else ["calibration.json"])


def test_interrupt_message_in_process(twin, tmp_path, capsys, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """main() turns a KeyboardInterrupt into status 130 and one line; if the command had
    already written its output (atomically) before the interrupt, it says so."""
    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(stripecal, "reconstruct_scan", interrupted)
    ply = tmp_path / "cloud.ply"
    assert main(["reconstruct", str(twin["cal"]), str(twin["scan"]), "-o", str(ply)]) == 130
    assert capsys.readouterr().err.strip() == "stripecal reconstruct: interrupted; nothing written"
    assert not ply.exists()

    # A stand-in cloud whose save() writes the file, then is interrupted (the real one
    # cannot be: reconstruct ignores Ctrl-C once it writes); SIGINT is back afterwards.
    class Cloud:
        skipped_frames: List[object] = []
        dropped = {"grazing": 0, "undistort": 0, "flagged": 0}

        def __len__(self) -> int:
            return 1

        def save(self, path: str, ascii: bool = False) -> None:
            Path(path).write_bytes(b"a complete file")
            raise KeyboardInterrupt

    handler = signal.getsignal(signal.SIGINT)
    monkeypatch.setattr(stripecal, "reconstruct_scan", lambda *a, **k: Cloud())
    assert main(["reconstruct", str(twin["cal"]), str(twin["scan"]), "-o", str(ply)]) == 130
    assert capsys.readouterr().err.strip() == f"stripecal reconstruct: interrupted; {ply} was already written"
    assert ply.read_bytes() == b"a complete file"
    assert signal.getsignal(signal.SIGINT) is handler
