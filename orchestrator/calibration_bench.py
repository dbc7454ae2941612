"""`rig bench calibration`: calibration accuracy against the simulator's truth.

It runs the simulator and the calibration code side by side, so it lives on
top of both.
"""

from __future__ import annotations

__all__ = ["run_bench"]


def run_bench(*, quick: bool = False) -> list[dict]:
    """``rig bench calibration``: error against the simulator's truth, and the
    capture time each costs on the rig, against the number of board poses (per
    camera) and of laser target heights.

    Rows ``cameras``: for the zenith and a 30° camera, the turntable angles
    used, reprojection RMS, focal-length error, camera-centre error, capture
    time of the session (all cameras) and fit time. Rows ``laser``: heights,
    angle error at tilt 0, residual, fitted uncertainty.
    """
