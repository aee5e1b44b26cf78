"""Checks that the wheel's build and `cargo test` enable the same features of every
dependency they share (crates/workspace-hack keeps them equal). When they differ, each
build recompiles what the other compiled into target/ (a fresh clone's `cargo test` once
rebuilt 61 crates after pip), and CI's time grows by minutes. Exits 1 naming the
dependencies and features to add to crates/workspace-hack/Cargo.toml.

    python scripts/check_shared_features.py
"""

import re
import subprocess
import sys

WHEEL = ["-e", "normal,build", "-p", "stripecal-py"]
TESTS = ["-e", "normal,build,dev", "-p", "stripecal", "-p", "stripecal-sim", "-p", "stripecal-benches"]


def features(args: list[str]) -> dict[tuple[str, str], set[str]]:
    out = subprocess.run(
        ["cargo", "tree", "--locked", "-f", "{p} [{f}]", "--prefix", "none", *args],
        check=True, capture_output=True, text=True,
    ).stdout
    found: dict[tuple[str, str], set[str]] = {}
    for line in out.splitlines():
        m = re.match(r"(\S+) (v\S+).*?\[(.*)\]", line.strip())
        if m:
            found.setdefault((m[1], m[2]), set()).update(f for f in m[3].split(",") if f)
    return found


def main() -> int:
    wheel, tests = features(WHEEL), features(TESTS)
    differ = [
        f"  {name} {ver}: wheel only {sorted(wheel[k] - tests[k])}, tests only {sorted(tests[k] - wheel[k])}"
        for k in sorted(wheel.keys() & tests.keys())
        for name, ver in [k]
        if wheel[k] != tests[k]
    ]
    if differ:
        print("the wheel's build and cargo test enable different features of shared dependencies;")
        print("add the union to crates/workspace-hack/Cargo.toml (build-dependencies for proc-macro crates):")
        print("\n".join(differ))
        return 1
    print(f"shared dependencies: {len(wheel.keys() & tests.keys())}, features equal in both builds")
    return 0


if __name__ == "__main__":
    sys.exit(main())
