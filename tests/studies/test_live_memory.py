"""``rig bench live-memory --quick``: a session's peak memory does not grow with its length,
because the live results are streamed to the archive (docs/daemon.md)."""

import pytest

from studies.live_memory import run

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


def test_peak_memory_stays_flat_from_200_to_496_frames():
    short, long = run(quick=True)
    assert (short["frames"], long["frames"]) == (200, 496)
    assert short["processed"] == short["frames"] and long["processed"] == long["frames"]
    # Held until the end the results took 70 → 148 MB; streamed, 45 → 47 MB.
    assert long["peak_mb"] < 1.15 * short["peak_mb"], (short, long)
