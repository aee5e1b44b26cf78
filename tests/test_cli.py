"""The stripecal command line."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pytest

import stripecal
from stripecal.cli import main


def test_info_prints_the_version(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info"]) == 0
    assert capsys.readouterr().out.strip() == f"stripecal {stripecal.__version__}"


def test_info_verbose(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", "--verbose"]) == 0
    out = capsys.readouterr().out
    assert "numpy" in out and "extension" in out


def test_no_command_prints_help_and_fails(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 2
    assert "usage" in capsys.readouterr().err


def test_module_entry_point() -> None:
    proc = subprocess.run([sys.executable, "-m", "stripecal", "info"], capture_output=True, text=True)
    assert proc.returncode == 0 and stripecal.__version__ in proc.stdout


@pytest.mark.skipif(shutil.which("stripecal") is None, reason="console script not on PATH")
def test_console_script() -> None:
    proc = subprocess.run(["stripecal", "--version"], capture_output=True, text=True)
    assert proc.returncode == 0 and stripecal.__version__ in proc.stdout
