"""``rig.frame_check``: a frame at the wrong tilt, lamp or axis position is named, with
what the devices read back and what the step planned; a matching frame is not."""

import numpy as np
import pytest

from rig.archive import FrameFlag
from rig.config import default_rig_config
from rig.frame_check import (
    FrameState,
    flag_summary,
    frame_mismatch,
    scan_tilts_deg,
    stale_frames,
    tilt_tolerance_deg,
)

CONFIG = default_rig_config()  # laser: 1°/s at 7.5 Hz, a tacho count is 1/24°


def test_scan_tilts_spread_over_the_sweep_no_closer_than_a_frame_period():
    coarse = scan_tilts_deg(CONFIG, (-6.0, 6.0), 7)
    np.testing.assert_allclose(coarse, [-6, -4, -2, 0, 2, 4, 6])
    # 0.1° asked, but the sheet moves 1/7.5° per frame: 90 frames cover it, 31 at the end
    fine = scan_tilts_deg(CONFIG, (6.0, -6.0), 121)
    np.testing.assert_allclose(np.diff(fine[:91]), -1 / 7.5)
    np.testing.assert_allclose(fine[90:], -6.0)
    assert tilt_tolerance_deg(CONFIG, fine) == pytest.approx(1 / 7.5)
    # a tolerance never finer than two tacho counts
    assert tilt_tolerance_deg(CONFIG, [0.0, 0.01]) == pytest.approx(2 / 24)


def test_a_frame_within_the_tolerance_matches():
    meant = FrameState(tilt_deg=1.0, lamps_on=frozenset({"lamp2"}), axes={"arc_deg": 30.0})
    around = [
        FrameState(tilt_deg=1.04, lamps_on=frozenset({"lamp2"}), axes={"arc_deg": 30.05}),
        FrameState(tilt_deg=1.1, lamps_on=frozenset({"lamp2"}), axes={"arc_deg": 29.95}),
    ]
    assert frame_mismatch(meant, around, tilt_tolerance_deg=0.133) is None


def test_a_frame_the_sheet_ran_away_from_names_the_tilts_read_back():
    why = frame_mismatch(
        FrameState(tilt_deg=-5.733),
        [FrameState(tilt_deg=-5.733), FrameState(tilt_deg=-4.5)],
        tilt_tolerance_deg=0.133,
    )
    assert why == (
        "laser tilt read back -5.733°…-4.500° around the exposure, planned -5.733° ± 0.133°"
    )


def test_a_frame_under_another_lamp_names_the_lamps_lit():
    why = frame_mismatch(
        FrameState(lamps_on=frozenset({"lamp2"})),
        [FrameState(lamps_on=frozenset({"lamp2", "lamp5"}))],
        tilt_tolerance_deg=0.0,
    )
    assert why == "lamps read back lit ['lamp2', 'lamp5'], planned ['lamp2']"
    dark = frame_mismatch(
        FrameState(lamps_on=frozenset({"lamp2"})), [FrameState(lamps_on=frozenset())],
        tilt_tolerance_deg=0.0,
    )  # fmt: skip
    assert dark == "lamps read back lit [], planned ['lamp2']"


def test_a_frame_at_the_wrong_turntable_angle_names_the_axis_and_every_problem():
    why = frame_mismatch(
        FrameState(lamps_on=frozenset({"lamp1"}), axes={"turntable_deg": 90.0, "arc_deg": 0.0}),
        [FrameState(lamps_on=frozenset(), axes={"turntable_deg": 90.5, "arc_deg": 0.0})],
        tilt_tolerance_deg=0.0,
    )
    assert why == (
        "lamps read back lit [], planned ['lamp1']; "
        "turntable_deg read back 90.500, planned 90.000 ± 0.1"
    )


def test_a_turntable_read_back_across_zero_is_where_it_was_sent():
    meant = FrameState(axes={"turntable_deg": 0.0})
    assert frame_mismatch(meant, [FrameState(axes={"turntable_deg": 359.95})],
                          tilt_tolerance_deg=0.0) is None  # fmt: skip


def test_what_the_devices_did_not_read_back_is_not_evidence():
    meant = FrameState(tilt_deg=2.0, lamps_on=frozenset({"lamp1"}), axes={"rail_deg": 10.0})
    assert frame_mismatch(meant, [FrameState()], tilt_tolerance_deg=0.1) is None


def test_a_frame_with_the_timestamp_of_the_one_before_is_stale():
    assert stale_frames([1.0, 1.2, 1.2, 1.1, 1.5]) == {
        2: "camera timestamp 1.200000 s is not later than the frame before's 1.200000 s "
        "(a stale frame)",
        3: "camera timestamp 1.100000 s is not later than the frame before's 1.200000 s "
        "(a stale frame)",
    }
    assert stale_frames([0.5]) == {}


def test_the_summary_counts_what_was_taken_again_and_what_is_left_out():
    flags = [
        (4, FrameFlag("cam0", 7, "laser tilt read back 6.000°…6.000°", True)),
        (4, FrameFlag("cam0", 8, "laser tilt read back 6.000°…6.000°", False)),
        (9, FrameFlag("cam2", 0, "lamps read back lit []", True)),
    ]
    assert flag_summary(flags) == {
        "frames": 3, "recaptured": 2, "left_out": 1, "steps": [4, 9],
        "reasons": {"4": "cam0 frame 7: laser tilt read back 6.000°…6.000°",
                    "9": "cam2 frame 0: lamps read back lit []"},
    }  # fmt: skip
    assert flag_summary([])["frames"] == 0
    many = flag_summary([(i, FrameFlag("cam0", 0, f"reason {i}", True)) for i in range(25)])
    assert many["steps"] == list(range(25)) and list(many["reasons"]) == [str(i) for i in range(10)]
