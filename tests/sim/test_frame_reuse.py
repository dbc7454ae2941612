"""Frames reused between steps equal the frames rendered from scratch.

The reference (``data/reference_frames.npz``) was rendered by the simulator
before hits, lamp visibility and shading were reused between frames
(``frame_sequence.py``). Tolerance: the signal before quantisation within
1e-9 DN (the reuse reorders float64 arithmetic only), the stored image equal.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim import Simulator
from tests.sim.frame_sequence import REFERENCE, SEQUENCE, render_sequence, sequence_scene


@pytest.fixture(scope="module")
def frames():
    with Simulator(sequence_scene()) as sim:
        return render_sequence(sim), dict(sim.counters)


def test_frames_equal_the_reference(frames):
    rendered, _ = frames
    with np.load(REFERENCE) as ref:
        assert len(ref.files) == 2 * len(SEQUENCE)
        for k in range(len(SEQUENCE)):
            np.testing.assert_allclose(
                rendered[f"signal_{k}"], ref[f"signal_{k}"], rtol=0, atol=1e-9, err_msg=f"frame {k}"
            )
            np.testing.assert_array_equal(rendered[f"image_{k}"], ref[f"image_{k}"], f"frame {k}")
