"""The extension's keyword-heavy callables take `(*args, **kwargs)` and bind them in Rust
(crates/stripecal-py/src/args.rs): each has a parameter list (`Params`) and, separately,
the `text_signature` Python shows (and `mypy.stubtest` checks against `_core.pyi`). This
checks that the two lists agree, without running anything: every parameter the signature
shows is accepted by the binder, the binder takes exactly the signature's positional
parameters, requires exactly its parameters without a default, and refuses a name the
signature does not show."""

from __future__ import annotations

import inspect
import re

import pytest

from stripecal import _core

BOUND = [
    "calibrate",
    "measure_sphere",
    "measure_ball_bar",
    "measure_plane",
    "verify",
    "plan_poses",
    "reconstruct_scan",
    "Board",
    "Calibration",
    "Truth",
    "ProfilerCalibration",
]


class _Unconvertible:
    """A value no parameter converts from."""


def _call(name: str, *args: object, **kwargs: object) -> str:
    with pytest.raises(TypeError) as info:
        getattr(_core, name)(*args, **kwargs)
    return str(info.value)


def _signature(name: str) -> inspect.Signature:
    text = getattr(_core, name).__text_signature__
    assert text, f"{name} has no text_signature"
    # `fix=...` stands for a default that is not a literal (a list); inspect reads it.
    return inspect.signature(getattr(_core, name))


@pytest.mark.parametrize("name", BOUND)
def test_every_shown_parameter_is_bound(name: str) -> None:
    for param in _signature(name).parameters.values():
        msg = _call(name, **{param.name: _Unconvertible()})
        assert "unexpected keyword argument" not in msg, (name, param.name, msg)


@pytest.mark.parametrize("name", BOUND)
def test_a_name_not_shown_is_refused(name: str) -> None:
    msg = _call(name, not_a_parameter_of_this_callable=1)
    assert "unexpected keyword argument 'not_a_parameter_of_this_callable'" in msg, msg
    assert msg.startswith((f"{name}()", f"{name}.__new__()")), msg


@pytest.mark.parametrize("name", BOUND)
def test_positional_and_required_parameters_agree(name: str) -> None:
    params = list(_signature(name).parameters.values())
    positional = [p for p in params if p.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD]
    required = [p for p in positional if p.default is inspect.Parameter.empty]
    # One more positional than the signature shows: refused, with the binder's count.
    msg = _call(name, *([_Unconvertible()] * (len(positional) + 1)))
    m = re.search(r"takes (?:at most |from \d+ to )?(\d+) positional arguments", msg)
    assert m, msg
    assert int(m.group(1)) == len(positional), (name, msg)
    # Nothing passed: the first required parameter is named as missing.
    msg = _call(name)
    assert f"missing required argument '{required[0].name}'" in msg, (name, msg)
    # All but the last required passed by keyword: the last one is named.
    kw = {p.name: _Unconvertible() for p in required[:-1]}
    msg = _call(name, **kw)
    assert f"missing required argument '{required[-1].name}'" in msg, (name, msg)
    # A keyword-only parameter passed by position is refused (checked by the count above).
