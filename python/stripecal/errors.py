"""The library's exceptions.

``StripecalError`` is the base class of stripecal's own errors. ``FormatError`` (a bad
file), ``InvalidInputError`` (a bad argument), ``DegenerateError`` (impossible geometry)
and ``DetectionError`` (no target found in an image, or not indexable without guessing)
are also ``ValueError``; ``ConvergenceError`` is also ``RuntimeError``.
``CalibrationQualityError`` (also ``ValueError``) is a calibration that failed its
quality gates: its ``checks`` say which and why, its ``calibration`` holds the result for
inspection (None when none exists). File-system failures raise the builtin ``OSError``
subclasses; array arguments of the wrong type raise ``TypeError``.

``BadImageError`` is the ``FormatError`` of a scan frame whose image cannot be used
(``reconstruct_scan``); its attributes ``frame``, ``line``, ``path`` and ``reason`` say
which frame (index and scan.csv line), which file and what is wrong.
"""

from stripecal._core import BadImageError as BadImageError
from stripecal._core import CalibrationQualityError as CalibrationQualityError
from stripecal._core import ConvergenceError as ConvergenceError
from stripecal._core import DegenerateError as DegenerateError
from stripecal._core import DetectionError as DetectionError
from stripecal._core import FormatError as FormatError
from stripecal._core import InvalidInputError as InvalidInputError
from stripecal._core import StripecalError as StripecalError

__all__ = [
    "BadImageError",
    "CalibrationQualityError",
    "ConvergenceError",
    "DegenerateError",
    "DetectionError",
    "FormatError",
    "InvalidInputError",
    "StripecalError",
]
