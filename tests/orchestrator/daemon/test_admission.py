"""What a session passes before it starts: plans of any shape are refused by name or
compiled, an archive's place is checked, and a resumed rig must be the recorded one."""

import math

import pytest
import tomli_w
from hypothesis import event, given
from hypothesis import strategies as st

from orchestrator.daemon.admission import (
    SessionError,
    check_archive_place,
    check_plan_size,
    rig_config_from_toml,
    rig_differences,
)
from rig.config import default_rig_config
from rig.errors import ConfigError, PlanError
from rig.plan import parse_plan
from rig.schedule import compile_plan
from tests.budgets import fuzz


def _mostly(valid, invalid):
    """``valid`` three times in four."""
    return st.one_of(valid, valid, valid, invalid)


_theta = st.floats(0, 85)  # in range: most examples should get as far as compiling
_angle = _theta | st.sampled_from([-1.0, 90.0, 361.0, math.nan, math.inf])
_listed = _mostly(
    st.lists(st.tuples(_theta, st.floats(0, 360)), min_size=1, max_size=5)
    | st.fixed_dictionaries(
        {"theta_deg": _theta, "count": st.integers(3, 8)}, optional={"phi0_deg": _angle}
    ),
    st.sampled_from(["H3", "", 7])
    | st.lists(st.lists(_angle, max_size=3), max_size=3)
    | st.fixed_dictionaries({"theta_deg": _angle, "count": st.integers(-2, 400)}),
)
_sampling = _listed | st.just("H2")  # at most 81 × 8 pairs: each example compiles fast
_capture = _mostly(st.fixed_dictionaries({"views": _sampling, "lights": _listed}), st.just({}))
_captures = {
    "btf": _capture,
    "ps": _capture,
    "mdf": st.fixed_dictionaries(
        {"views": _sampling, "laser_locations": _listed},
        optional={"scan_step_deg": st.floats(-1, 20)},
    ),
    "fixed": st.lists(
        st.fixed_dictionaries({"turntable_deg": _angle, "lamp": st.sampled_from(["L0", "nope"])}),
        min_size=1,
        max_size=2,
    ),
}
_plan = st.fixed_dictionaries(
    {
        "sample": st.fixed_dictionaries(
            {"name": st.sampled_from(["s"] * 9 + ["bad name", "", "a" * 130])}
        ),
        "captures": st.one_of(
            *(
                st.fixed_dictionaries(
                    {first: _captures[first]},
                    optional={k: v for k, v in _captures.items() if k != first},
                )
                for first in ("btf", "ps", "mdf")
            ),
            st.fixed_dictionaries({}, optional=_captures),
        ),
    },
    optional={
        "exposure": st.fixed_dictionaries(
            {},
            optional={
                "exposure_s": _mostly(st.floats(0.001, 1), st.sampled_from([0.0, -1.0, 61.0])),
                "hdr_brackets": st.sampled_from(
                    [[1.0], [1.0, 2.0, 4.0]] * 3 + [[], [1.0, 1.0], [-2.0]]
                ),
                "laser_exposure_s": _mostly(st.floats(0.0001, 0.01), st.just(0.5)),
            },
        ),
        "resolution": st.fixed_dictionaries({"scale": _mostly(st.floats(0.01, 1), st.just(0.0))}),
        "output": st.fixed_dictionaries(
            {"archive": st.sampled_from(["o/{sample}.zarr"] * 6 + ["o/{x}.zarr", "o/{", "o/{0}"])}
        ),
    },
)


def _admit(text: str):
    """The schedule of plan ``text``, or the error that refused it."""
    try:
        plan = parse_plan(text, source="fuzzed.toml")
        check_plan_size(plan, "fuzzed.toml")
        return compile_plan(plan, default_rig_config())
    except (PlanError, ConfigError) as err:
        return err


@fuzz()
@given(_plan)
def test_any_plan_is_compiled_or_refused_naming_a_field(data):
    outcome = _admit(tomli_w.dumps(data))
    event(type(outcome).__name__)  # --hypothesis-show-statistics: how many compiled
    if isinstance(outcome, PlanError):
        assert "fuzzed.toml" in str(outcome) or "plan vs rig config" in str(outcome)
    elif not isinstance(outcome, ConfigError):
        assert outcome.steps
        assert math.isfinite(outcome.estimate.total_s) and outcome.estimate.total_s > 0


def test_an_archive_place_that_exists_or_sits_under_a_file_is_refused(tmp_path):
    (tmp_path / "taken.zarr").mkdir()
    (tmp_path / "afile").write_text("")
    with pytest.raises(SessionError, match="already exists") as info:
        check_archive_place(tmp_path / "taken.zarr", "args.archive")
    assert info.value.field == "args.archive"
    with pytest.raises(SessionError, match="afile is a file, not a folder"):
        check_archive_place(tmp_path / "afile" / "deeper" / "x.zarr", "args.plan_toml")
    check_archive_place(tmp_path / "new" / "deeper" / "x.zarr", "args.archive")


def test_only_device_sections_and_calibration_may_differ():
    recorded = default_rig_config()
    device = recorded.lamp_bank.device
    registers = device.registers.model_copy(update={"coils": 8})  # rewired, too
    moved_device = device.model_copy(
        update={"port": 1502, "host": "10.0.0.7", "registers": registers}
    )
    lamp_bank = recorded.lamp_bank.model_copy(update={"device": moved_device})
    moved = recorded.model_copy(update={"lamp_bank": lamp_bank, "calibration": "new.toml"})
    assert rig_differences(recorded, moved) == []
    cameras = list(moved.camera_arc.cameras)
    cameras[3] = cameras[3].model_copy(update={"theta_deg": cameras[3].theta_deg + 1})
    tilted = moved.model_copy(
        update={"camera_arc": moved.camera_arc.model_copy(update={"cameras": tuple(cameras)})}
    )
    assert rig_differences(recorded, tilted) == [
        ("camera_arc.cameras[3].theta_deg", cameras[3].theta_deg - 1, cameras[3].theta_deg)
    ]
    fewer = moved.model_copy(
        update={"camera_arc": moved.camera_arc.model_copy(update={"cameras": tuple(cameras[:2])})}
    )
    assert [d[0] for d in rig_differences(recorded, fewer)] == ["camera_arc.cameras"]


def test_a_rig_config_sent_as_text_is_checked_naming_the_field():
    with pytest.raises(SessionError, match=r"new\.toml is not valid TOML") as info:
        rig_config_from_toml("[turntable", source="new.toml")
    assert info.value.field == "args.config_toml"
    with pytest.raises(SessionError, match=r"new\.toml: invalid: turntable\.axis\.speed_deg_s"):
        rig_config_from_toml("[turntable.axis]\nspeed_deg_s = -3\n", source="new.toml")
    text = tomli_w.dumps(default_rig_config().model_dump(mode="json", exclude_none=True))
    assert rig_config_from_toml(text, source="same.toml") == default_rig_config()
