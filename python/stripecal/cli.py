"""The ``stripecal`` command-line interface.

Each subcommand is one ``cmd_<name>(args) -> int`` function plus one ``_add_<name>``
function that declares its arguments; ``build_parser`` lists the ``_add_`` functions.
To add a subcommand, write both and append the ``_add_`` function to ``_SUBCOMMANDS``.
The CLI only parses arguments, calls the library and prints: no numerics here.
"""

from __future__ import annotations

import argparse
import platform
import sys
from typing import Callable, List, Optional, Sequence

import numpy as np

import stripecal


def cmd_info(args: argparse.Namespace) -> int:
    """Prints the version (and with --verbose, where things come from)."""
    print(f"stripecal {stripecal.__version__}")
    if args.verbose:
        print(f"python {platform.python_version()} ({sys.executable})")
        print(f"numpy {np.__version__}")
        print(f"extension {stripecal._core.__file__}")
    return 0


def _add_info(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("info", help="print the version", description=cmd_info.__doc__)
    p.add_argument("-v", "--verbose", action="store_true", help="also print versions and paths")
    p.set_defaults(func=cmd_info)


_SUBCOMMANDS: List[Callable[[argparse._SubParsersAction[argparse.ArgumentParser]], None]] = [
    _add_info,
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="stripecal",
        description="Calibration and measurement for a robot-mounted laser-stripe sensor.",
    )
    parser.add_argument(
        "--version", action="version", version=f"%(prog)s {stripecal.__version__}"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in _SUBCOMMANDS:
        add(sub)
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of the ``stripecal`` console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    func: Optional[Callable[[argparse.Namespace], int]] = getattr(args, "func", None)
    if func is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        return func(args)
    except (stripecal.StripecalError, OSError) as e:
        print(f"stripecal {args.command}: error: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    raise SystemExit(main())
