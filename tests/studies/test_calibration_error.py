"""`rig bench calibration --quick`: its rows, each against the simulator's truth."""

import pytest

from studies.calibration_error import run

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def rows():
    return run(quick=True)


def test_camera_rows_per_pose_count_within_truth(rows):
    cameras = [row for row in rows if row["row"] == "cameras"]
    assert [row["poses"] for row in cameras] == [4, 6, 12]
    for row in cameras:
        assert row["images_kept"] == row["poses"]
        assert row["rms_px"] < 0.2
        assert abs(row["focal_error_pct"]) < 1.0
        assert row["centre_error_mm"] < 5.0
    # More poses cost more capture time on the rig.
    assert cameras[0]["capture_s"] < cameras[1]["capture_s"] < cameras[2]["capture_s"]


def test_laser_rows_per_height_count_within_truth(rows):
    laser = [row for row in rows if row["row"] == "laser"]
    assert [row["heights"] for row in laser] == [2, 3, 5]
    for row in laser:
        assert abs(row["angle_error_deg"]) < 0.1
    # Three or more heights leave a residual to estimate the uncertainty from.
    assert all(row["angle_std_deg"] < 0.05 for row in laser[1:])
