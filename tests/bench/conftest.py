"""Benchmarks are not part of the default test run: they need a release build of the
extension and a quiet machine. Run them explicitly (see BENCHMARKS.md):

    STRIPECAL_BENCH=1 python -m pytest tests/bench -s
"""

import os

if not os.environ.get("STRIPECAL_BENCH"):
    collect_ignore_glob = ["test_*.py"]
