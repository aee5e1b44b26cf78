"""The Python record types of calibration.json (``stripecal.types``' TypedDicts) against
the keys the core writes each record with (``stripecal._core.record_keys()``, taken
from the Rust writers): a key added to or removed from a record on one side only
fails here."""

import typing

import stripecal.types as types
from stripecal import _core


def _keys(name: str) -> set:
    return set(typing.get_type_hints(getattr(types, name)))


def test_every_record_type_has_the_keys_the_core_writes() -> None:
    described = _core.record_keys()
    assert len(described) >= 15, sorted(described)
    for name, keys in described.items():
        if name == "CalibrationExtra":
            # the TypedDict also names top-level keys without a typed record
            missing = set(keys) - _keys(name)
            assert not missing, f"{name} lacks {sorted(missing)}"
        else:
            assert set(keys) == _keys(name), (name, sorted(keys), sorted(_keys(name)))

