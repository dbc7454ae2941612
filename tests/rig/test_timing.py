"""The timing model, against durations worked out by hand from the default rig's limits.

Turntable: 30 °/s, 60 °/s², settle 0.3 s. Light arc: 20 °/s, 40 °/s², settle 0.5 s.
Cameras: readout 1/15 s. Lamps: warm-up 0.05 s. Laser: 7.5 Hz, sheet at 1 °/s.
"""

import pytest

from rig.config import default_rig_config
from rig.plan import parse_plan
from rig.schedule import compile_plan
from rig.timing import motion_s, readout_s, scan_s, shots_s, step_timing

CONFIG = default_rig_config()


def test_axes_move_together_and_the_slower_settle_counts():
    # turntable 90°: cruise, 90/30 + 30/60 = 3.5 s; arc 30°: 30/20 + 20/40 = 2.0 s
    move, settle = motion_s(CONFIG, (0.0, 0.0), (90.0, 30.0))
    assert (move, settle) == pytest.approx((3.5, 0.5))
    # turntable 5° back only: never reaches cruise, 2·√(5/60) s; the arc needs no settling
    move, settle = motion_s(CONFIG, (90.0, 30.0), (85.0, 30.0))
    assert (move, settle) == pytest.approx((2 * (5 / 60) ** 0.5, 0.3))
    move, settle = motion_s(CONFIG, (10.0, 20.0), (10.0, 20.0))
    assert (move, settle) == (0.0, 0.0)


def test_cameras_firing_together_read_out_once_per_exposure():
    cameras = ["cam0", "cam3", "cam7"]
    assert readout_s(CONFIG, cameras) == pytest.approx(1 / 15)
    assert shots_s(CONFIG, cameras, [0.01, 0.04]) == pytest.approx(0.05 + 2 / 15)
    assert shots_s(CONFIG, cameras, [0.01, 0.04], scale=0.5) == pytest.approx(0.05 + 1 / 15)


def test_a_scan_lasts_its_frames_or_its_sweep_and_sweeps_back():
    assert scan_s(CONFIG, 31, 12.0) == pytest.approx(12.0 + 12.0)  # the sweep is slower
    assert scan_s(CONFIG, 150, 12.0) == pytest.approx(20.0 + 12.0)  # the frames are slower


def test_a_lamp_step_is_move_lamp_on_and_off_and_shots():
    plan = parse_plan(
        '[sample]\nname = "t"\n[[captures.fixed]]\nturntable_deg = 90\narc_deg = 30\n'
        'lamp = "lamp2"\ncameras = ["cam0", "cam1"]\n'
        "[exposure]\nexposure_s = 0.02\nhdr_brackets = [1, 4]\n"
    )
    (step,) = compile_plan(plan, CONFIG).steps
    timing = step_timing(CONFIG, step, (0.0, 0.0))
    assert timing.as_dict() == pytest.approx(
        {"move_s": 3.5, "settle_s": 0.5, "lamp_s": 0.1, "capture_s": 0.1 + 2 / 15,
         "total_s": 4.1 + 0.1 + 2 / 15}
    )  # fmt: skip
