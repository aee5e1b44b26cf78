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

step "pip install -e '.[test]'  (builds stripecal._core with maturin)"
"$PYTHON" -m pip install --quiet -e '.[test]'

# The core's and the twin's unit tests and their one integration-test binary each (the
# pyo3 crate has no test binary). Examples and criterion benches are not built here:
# `cargo clippy --all-targets` builds them before every submission (CONTRIBUTING.md).
step "cargo test  (stripecal, stripecal-sim: unit and integration tests)"
cargo test --quiet -p stripecal -p stripecal-sim --lib --tests

# One worker per core, each taking whole test modules (--dist loadfile), so that a
# module's fixtures still render their twin once: 314 s serial -> 225 s on 2 cores.
step "pytest  (a test module per worker, one worker per core)"
"$PYTHON" -m pytest -q -n auto --dist loadfile

step "all tests passed"
