"""The Python API's layout: the area submodules re-export the extension's names, each
name lives in exactly one of them, and the top level re-exports them unchanged."""

from __future__ import annotations

import importlib
import types
from typing import Dict, List

import pytest

import stripecal
import stripecal._core

AREAS = ["model", "io", "vision", "calib", "reconstruction", "sim", "errors"]
# top-level public names that are not API objects of one area
NOT_IN_AREAS = {"__version__", "sim"}


def area_modules() -> Dict[str, types.ModuleType]:
    return {name: importlib.import_module(f"stripecal.{name}") for name in AREAS}


@pytest.mark.parametrize("area", AREAS)
def test_area_module_documented_and_complete(area: str) -> None:
    mod = importlib.import_module(f"stripecal.{area}")
    assert mod.__doc__ and len(mod.__doc__.strip()) > 40, f"stripecal.{area} needs a module docstring"
    assert len(mod.__all__) == len(set(mod.__all__))
    for name in mod.__all__:
        assert hasattr(mod, name), f"stripecal.{area}.__all__ names {name}, which it lacks"


@pytest.mark.parametrize("area", [a for a in AREAS if a != "sim"])
def test_area_names_are_the_top_level_objects(area: str) -> None:
    mod = importlib.import_module(f"stripecal.{area}")
    for name in mod.__all__:
        assert getattr(stripecal, name) is getattr(mod, name), f"stripecal.{name} is not stripecal.{area}.{name}"
        assert getattr(stripecal._core, name) is getattr(mod, name), f"stripecal.{area}.{name} is not the extension's"


def test_sim_area() -> None:
    # the twin's module wraps the extension (Twin takes a config dict): its names are
    # reached as stripecal.sim.X, the module itself is a top-level name
    assert stripecal.sim is importlib.import_module("stripecal.sim")
    assert set(stripecal.sim.__all__) == {"Twin", "calibration_pose_set", "preset", "presets", "profiler_truth", "surface_errors"}


def test_every_top_level_name_in_exactly_one_area() -> None:
    mods = area_modules()
    for name in stripecal.__all__:
        assert hasattr(stripecal, name), f"stripecal.__all__ names {name}, which it lacks"
        if name in NOT_IN_AREAS:
            continue
        homes: List[str] = [area for area, mod in mods.items() if name in mod.__all__]
        assert len(homes) == 1, f"stripecal.{name} is in {homes or 'no area module'}"


def test_no_area_name_missing_from_top_level() -> None:
    for area, mod in area_modules().items():
        if area == "sim":
            continue
        for name in mod.__all__:
            assert name in stripecal.__all__, f"stripecal.{area}.{name} is not re-exported at the top level"


def test_extension_names_covered() -> None:
    # every public name of the extension is reachable from one area module (the twin's
    # raw pieces through stripecal.sim)
    mods = area_modules()
    sim_core = {"Twin", "sim_config", "sim_presets", "sim_surface_errors"}
    for name in stripecal._core.__all__:
        if name in sim_core:
            continue
        homes = [area for area, mod in mods.items() if name in mod.__all__]
        assert len(homes) == 1, f"stripecal._core.{name} is in {homes or 'no area module'}"


def test_reconstruct_is_still_the_function() -> None:
    # the area module is `reconstruction` so that this stays true
    assert callable(stripecal.reconstruct)
    assert stripecal.reconstruct is stripecal._core.reconstruct
    assert isinstance(stripecal.reconstruction, types.ModuleType)


def test_types_are_runtime_typeddicts() -> None:
    import stripecal.types as t

    for name in t.__all__:
        assert hasattr(t, name)
    assert t.CalibrationView.__required_keys__ >= {"view", "used", "note"}
    assert t.CalibrationUncertainty.__total__ is False
