"""Lamp steps whose frames did not record the step's state, through the daemon with
soft devices: a stray lamp, a bumped turntable, a stale frame. Each is flagged in the
step record naming why, taken again after the rig is driven again, and reported."""

import pytest

from orchestrator.client import DaemonClient, wait_for_state
from rig.archive import Archive
from rig.plan import parse_plan
from rig.schedule import compile_plan
from tests.orchestrator.daemon.conftest import LAMP_PLAN, TINY_PLAN, running_daemon
from tests.orchestrator.daemon.soft import soft_image


def _session(config, rig, plan_text, path):
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        client.request("submit", plan_toml=plan_text, source="test", archive=str(path))
        return wait_for_state(endpoints, ("done",), settled=True)


@pytest.mark.parametrize(
    ("fault", "why"),
    [("stray_lamp", "lamps read back lit"), ("bump", "turntable_deg read back")],
)
def test_a_frame_taken_in_the_wrong_state_is_flagged_and_taken_again(
    config, rig, tmp_path, fault, why
):
    steps = compile_plan(parse_plan(LAMP_PLAN), config).steps
    step = steps[3]
    camera = step.cameras[0]
    # the camera's fourth trigger is step 3's: the disturbance comes during its exposure
    for _ in range(3):
        rig.faults.arm(f"{camera}.trigger", "none")
    rig.faults.arm(f"{camera}.trigger", fault)
    final = _session(config, rig, LAMP_PLAN, tmp_path / "s.zarr")
    with Archive.open(tmp_path / "s.zarr") as archive:
        records = {r.index: r for r in archive.step_table()}
        frame = archive.read_frame(step.index, camera, 0)
    flagged = {r.index: r.flags for r in records.values() if r.flags}
    assert list(flagged) == [step.index]
    # the state is the step's: every camera's frame of it is flagged, and re-taken
    assert {f.camera for f in flagged[step.index]} == set(step.cameras)
    assert all(f.recaptured and why in f.reason for f in flagged[step.index])
    # the archived frame is the re-take: the step's own lamp and turntable angle
    expected = soft_image(
        _format(config, camera), camera, *step.pose, (step.source,),
        False, step.exposures_s[0],
    )  # fmt: skip
    assert (frame == expected).all()
    summary = final["session"]["flagged"]
    assert summary["frames"] == len(step.cameras) and summary["steps"] == [step.index]
    assert summary["recaptured"] == len(step.cameras) and summary["left_out"] == 0
    assert why in summary["reasons"][str(step.index)]


def test_a_stale_frame_is_flagged_by_its_timestamp(config, rig, tmp_path):
    """A camera hands back its buffered frame (the bracket's second frame carries the
    first's timestamp): flagged as stale, taken again."""
    steps = compile_plan(parse_plan(TINY_PLAN), config).steps
    step = next(s for s in steps if s.kind == "btf")
    camera = step.cameras[0]
    rig.faults.arm(f"{camera}.read", "none")
    rig.faults.arm(f"{camera}.read", "stale")
    _session(config, rig, TINY_PLAN, tmp_path / "t.zarr")
    with Archive.open(tmp_path / "t.zarr") as archive:
        flags = [f for r in archive.step_table() for f in r.flags]
    assert [(f.camera, f.sub, f.recaptured) for f in flags] == [(camera, 1, True)]
    assert "is not later than the frame before's" in flags[0].reason


def _format(config, camera):
    from orchestrator.daemon import frame_formats

    return frame_formats(config, scale=parse_plan(LAMP_PLAN).resolution.scale)[camera]
