"""The Python record types of calibration.json (``stripecal.types``' TypedDicts) against
the keys the core writes each record with (``stripecal._core.record_keys()``, taken
from the Rust writers): a key added to or removed from a record on one side only
fails here."""

import typing
from pathlib import Path

import stripecal
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



def test_a_calibration_built_from_another_keeps_its_records() -> None:
    # a file written before the typed records, then Calibration(..., extra=its extra)
    path = Path(__file__).parent.parent / "crates/stripecal/tests/data/held_v1.json"
    c = stripecal.load_calibration(path)
    assert c.mount == "robot" and c.views and c.leave_one_out and c.robot_pose_noise
    d = stripecal.Calibration(c.camera, c.laser_plane, c.hand_cam, c.base_board, c.robot,
                              c.quality, c.uncertainty, c.extra)
    # the folds' laser planes are renormalised when read again (as from a file): to 1e-12
    def folds_apart(x: dict) -> tuple:
        views = [{k: v for k, v in w.items() if k != "fold"} for w in x["views"]]
        return {**x, "views": views}, [w["fold"]["laser_plane"]["d_mm"] for w in x["views"]]

    (dl, dd), (cl, cd) = folds_apart(d.extra["leave_one_out"]), folds_apart(c.extra["leave_one_out"])
    assert dl == cl and all(abs(a - b) < 1e-12 * b for a, b in zip(dd, cd)) and len(dd) == len(cd)
    others = {k: v for k, v in d.extra.items() if k != "leave_one_out"}
    assert others == {k: v for k, v in c.extra.items() if k != "leave_one_out"}
    assert d.views == c.views and d.warnings == c.warnings and d.warnings
    assert d.leave_one_out is not None and d.board_scale == c.board_scale
    assert d.robot_pose_noise == c.robot_pose_noise and d.robot_calibration is None
    bench = stripecal.load_calibration(path.with_name("bench_v1.json"))
    assert bench.mount == "bench" and bench.is_bench and bench.extra["bench"] is True


def test_the_summary_and_the_stripe_channel_are_typed_records() -> None:
    import json

    path = Path(__file__).parent.parent / "crates/stripecal/tests/data/held_v1.json"
    c = stripecal.load_calibration(path)
    s = c.summary
    assert s is not None and set(s) <= _keys("CalibrationSummary")
    assert {k: c.extra[k] for k in s} == s  # type: ignore[literal-required]
    assert c.stripe_channel is None and c.stripe_channel_scores is None
    scores = {"gray": 12.0, "red": 340.0, "green": 5.0, "blue": 0.0}
    extra = {**c.extra, "stripe_channel": "red", "stripe_channel_scores": scores}
    d = stripecal.Calibration(c.camera, c.laser_plane, c.hand_cam, c.base_board, c.robot,
                              c.quality, c.uncertainty, extra)
    assert d.stripe_channel == "red" and d.stripe_channel_scores == scores
    assert list(d.stripe_channel_scores) == list(scores)
    keys = list(json.loads(d.to_json()))
    assert keys[-2:] == ["stripe_channel", "stripe_channel_scores"]
    back = stripecal.Calibration.from_json(d.to_json())
    assert back.stripe_channel == "red" and back.stripe_channel_scores == scores
    # a channel this version does not know stays in `extra`, as the file has it
    odd = stripecal.Calibration(c.camera, c.laser_plane, c.hand_cam, c.base_board, c.robot,
                                extra={"stripe_channel": "purple"})
    assert odd.stripe_channel is None and odd.extra["stripe_channel"] == "purple"


def test_a_profiler_calibrations_records_are_typed() -> None:
    # a file written before the typed records: every record through its getter, the
    # same as the file's key; ProfilerCalibration(..., extra=its extra) keeps them
    import json

    path = Path(__file__).parent.parent / "crates/stripecal/tests/data/profiler_v1.json"
    text = path.read_text()
    j = json.loads(text)
    c = stripecal.ProfilerCalibration.from_json(text)
    # the records' bytes written back in their place (the pose's rotation vector goes
    # through a rotation matrix, as before the records)
    tail = '\n  "robot_calibration"'
    assert c.to_json()[c.to_json().index(tail):] == text[text.index(tail):]
    assert list(json.loads(c.to_json())) == list(j)
    assert c.views == j["views"] and len(c.views) == 10
    assert c.adjustment == j["adjustment"] and c.mirror == j["mirror"]
    assert c.diameter_check == j["diameter_check"] and c.leave_one_out == j["leave_one_out"]
    assert c.robot_calibration == j["robot_calibration"]
    assert c.sphere_diameter_estimated is False and c.warnings == []
    assert c.extra == {k: j[k] for k in _core.record_keys()["ProfilerExtra"] if k in j}
    d = stripecal.ProfilerCalibration(c.hand_sensor, c.sphere_center_mm, c.sphere_diameter_mm,
                                      c.robot, extra={**c.extra, "warnings": ["w"], "later": 1})
    assert d.views == c.views and d.mirror == c.mirror and d.warnings == ["w"]
    assert d.robot_calibration == c.robot_calibration and d.extra["later"] == 1
    odd = stripecal.ProfilerCalibration(c.hand_sensor, c.sphere_center_mm, 80.0,
                                        extra={"mirror": "not a record"})
    assert odd.mirror is None and odd.extra == {"mirror": "not a record"}


def test_many_keyword_callables_keep_their_python_signatures() -> None:
    import inspect

    import pytest

    sig = inspect.signature(stripecal.calibrate)
    assert list(sig.parameters)[:3] == ["dataset", "distortion", "method"]
    assert sig.parameters["method"].default == "one-stage"
    assert sig.parameters["distortion"].kind is inspect.Parameter.KEYWORD_ONLY
    with pytest.raises(TypeError, match=r"calibrate\(\) got an unexpected keyword argument 'robots'"):
        stripecal.calibrate("nowhere", robots="fixed")  # type: ignore[call-arg]
    with pytest.raises(TypeError, match=r"calibrate\(\) takes at most 1 positional"):
        stripecal.calibrate("nowhere", None)  # type: ignore[misc]
    with pytest.raises(TypeError, match=r"calibrate\(\) argument 'robust'"):
        stripecal.calibrate("nowhere", robust="yes")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"Board\(\) missing required argument 'circle_diameter_mm'"):
        stripecal.Board(4, 5, 10.0)  # type: ignore[call-arg]
    with pytest.raises(TypeError, match=r"Board\(\) got multiple values for argument 'rows'"):
        stripecal.Board(4, 5, 10.0, 5.0, rows=4)  # type: ignore[misc]
    b = stripecal.Board(4, 5, 10.0, 5.0, None, [], True, "circles")
    assert b == stripecal.Board(rows=4, cols=5, pitch_mm=10.0, circle_diameter_mm=5.0, markers=[])
    with pytest.raises(OverflowError):
        stripecal.reconstruct_scan("nowhere", "nowhere", drop_flags=300)


def test_the_twins_truth_keys_are_typed() -> None:
    from stripecal import sim

    twin = sim.Twin(sim.preset("hp3-paper", seed=0))
    extra = twin.truth().extra
    assert set(extra) <= _keys("TruthExtra"), sorted(set(extra) - _keys("TruthExtra"))
    assert {"laser_emitter_mm", "stripe_direction", "table", "plate", "sim_config"} <= set(extra)
    assert set(extra["plate"]) == _keys("TruthPlate") and set(extra["table"]) == _keys("TwinPlane")
