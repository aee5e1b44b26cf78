"""The hand-written stub python/stripecal/_core.pyi matches the built extension, and the
package type-checks."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", *args], cwd=ROOT, capture_output=True, text=True, timeout=600
    )


def test_stubtest_core() -> None:
    proc = run("mypy.stubtest", "stripecal._core")
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_mypy_package() -> None:
    proc = run("mypy", "--no-incremental", "python/stripecal")
    assert proc.returncode == 0, proc.stdout + proc.stderr
