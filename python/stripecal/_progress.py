"""A small progress bar for the CLI: drawn on stderr when it is a terminal, silent
otherwise (logs and pipes stay clean)."""

from __future__ import annotations

import sys
import time
from typing import Optional, TextIO


class Progress:
    """``Progress()(stage, done, total)`` redraws one line ``stage [####    ] 12/40 3.1/s``;
    ``extra`` (e.g. a second rate) is appended to the line."""

    def __init__(self, stream: Optional[TextIO] = None, width: int = 30) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = bool(getattr(self.stream, "isatty", lambda: False)())
        self.width = width
        self._stage = ""
        self._t0 = time.monotonic()

    def __call__(self, stage: str, done: int, total: int, extra: str = "") -> None:
        if not self.enabled:
            return
        if stage != self._stage:
            if self._stage:
                self.stream.write("\n")
            self._stage = stage
            self._t0 = time.monotonic()
        frac = done / total if total else 1.0
        fill = int(round(frac * self.width))
        dt = time.monotonic() - self._t0
        rate = f" {done / dt:5.1f}/s" if dt > 0 and done else ""
        bar = "#" * fill + " " * (self.width - fill)
        self.stream.write(f"\r{stage:<18} [{bar}] {done}/{total}{rate}{extra}")
        if done >= total:
            self.stream.write("\n")
            self._stage = ""
        self.stream.flush()
