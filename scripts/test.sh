#!/usr/bin/env bash
# Builds and installs stripecal with its test extras, then runs every test: the Rust
# workspace's tests and the Python tests. Works from a fresh clone; fails on the first
# failing step.
#
#   bash scripts/test.sh            (PYTHON=python3.12 bash scripts/test.sh for another interpreter)
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON="${PYTHON:-python}"
# Build the extension with cargo's dev profile, into the same target/ directory as
# `cargo test`, so the two builds share the workspace's compiled dependencies.
export MATURIN_PEP517_ARGS="${MATURIN_PEP517_ARGS:---profile dev}"
export PIP_DISABLE_PIP_VERSION_CHECK=1 PIP_ROOT_USER_ACTION=ignore
# One build from scratch, never rebuilt by this script: incremental compilation's caches
# would only cost time to write (CARGO_INCREMENTAL=1 in the environment keeps them).
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"

start=$SECONDS
step() { printf '\n==> %s  (%ss)\n' "$*" "$((SECONDS - start))"; }

step "the wheel's and the tests' builds share their dependencies (crates/workspace-hack)"
"$PYTHON" scripts/check_shared_features.py

# The Rust libraries the wheel links (the core, the twin, their dependencies) are compiled
# while pip downloads and installs the Python packages: pip builds the extension last, and
# its cargo then waits for this build's lock and compiles the binding crate alone (the
# same units: workspace-hack gives this build the wheel's features). A fresh clone's pip
# spent ~60-90 s downloading with both cores idle.
step "cargo build of the wheel's Rust libraries, beside pip's downloads"
prebuild_log="$(mktemp)"
cargo build --quiet -p stripecal -p stripecal-sim -p workspace-hack --lib > "$prebuild_log" 2>&1 &
prebuild_pid=$!

step "pip install -e '.[test]'  (builds stripecal._core with maturin)"
"$PYTHON" -m pip install --quiet -e '.[test]'
prebuild=0
wait "$prebuild_pid" || prebuild=$?
cat "$prebuild_log"
rm -f "$prebuild_log"
if [ "$prebuild" -ne 0 ]; then
    step "FAILED: cargo build exit $prebuild"
    exit 1
fi

# The Rust tests and the Python tests run side by side: each alone leaves a core idle
# while it links, and at the end of each test binary and of pytest's last module (the
# machine's cores are then shared by four jobs instead of two). pytest's output is kept
# in a file and printed after the Rust tests'; the script fails if either fails.
#
# The core's and the twin's unit tests and their one integration-test binary each (the
# pyo3 crate has no test binary). Examples and criterion benches are not built here:
# `cargo clippy --all-targets` builds them before every submission (CONTRIBUTING.md).
# pytest: one worker per core, each taking whole test modules (--dist loadfile), so that
# a module's fixtures still render their twin once.
# --durations: the 15 slowest tests and set-ups are listed, to see where CI time goes.
# The Rust tests' build and run are the longer of the two (a fresh clone's run: pytest
# done at 643 s, the Rust tests at 928 s), so pytest runs at a lower priority: it takes
# what the Rust build leaves idle (its links, its single-crate tail) instead of half the
# cores. At nice 10 pytest became the tail (Rust 862 s, pytest 914 s). After the twin's
# renderer got cheaper (2026-11-30), nice 6 left the Rust tests the tail (pytest done at
# 805 s, Rust 876 s) and nice 8 ends both together (Rust 863 s, pytest 869 s; 870 s in all).
pylog="$(mktemp)"
trap 'rm -f "$pylog"' EXIT
step "pytest started in the background  (a test module per worker, one worker per core)"
nice -n 8 "$PYTHON" -m pytest -q -n auto --dist loadfile --durations=15 > "$pylog" 2>&1 &
pytest_pid=$!

step "cargo test  (stripecal, stripecal-sim: unit and integration tests)"
rust=0
cargo test --quiet -p stripecal -p stripecal-sim --lib --tests || rust=$?

step "pytest  (its output)"
py=0
wait "$pytest_pid" || py=$?
cat "$pylog"
if [ "$rust" -ne 0 ] || [ "$py" -ne 0 ]; then
    step "FAILED: cargo test exit $rust, pytest exit $py"
    exit 1
fi

step "all tests passed"
