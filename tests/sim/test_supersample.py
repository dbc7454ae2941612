"""``render.supersample``: k×k shading points per pixel, averaged as a sensor integrates."""

from __future__ import annotations

import numpy as np
import pytest

from rig.errors import ConfigError
from sim import Simulator, scene_from_dict

LAMPS = ("lamp3",)


def _scene(scale: float, supersample: int):
    return scene_from_dict(
        {
            "sample": {"generator": "bumps"},
            "render": {"scale": scale, "supersample": supersample},
            "effects": ["shadows"],
        }
    )


def _signal(scale: float, supersample: int) -> np.ndarray:
    with Simulator(_scene(scale, supersample)) as sim:
        return sim.render_state("cam2", turntable_deg=20.0, lamps_on=LAMPS).signal


def test_supersampling_is_the_area_average_of_a_finer_render():
    coarse = _signal(0.0625, 2)  # 128 × 96, 2 × 2 points per pixel
    fine = _signal(0.125, 1)  # 256 × 192, one point per pixel
    h, w = coarse.shape[:2]
    expected = fine.reshape(h, 2, w, 2, -1).mean(axis=(1, 3))
    np.testing.assert_allclose(coarse, expected, rtol=1e-5, atol=1e-3)


def test_supersampling_softens_edges_without_changing_the_mean():
    plain, smooth = _signal(0.0625, 1), _signal(0.0625, 3)
    assert smooth.shape == plain.shape
    assert abs(smooth.mean() - plain.mean()) < 0.02 * plain.mean()
    # marker and yarn edges: the area average fills in levels a point sample skips
    step = np.abs(np.diff(plain[..., 1], axis=1)).max()
    smooth_step = np.abs(np.diff(smooth[..., 1], axis=1)).max()
    assert smooth_step < step


@pytest.mark.parametrize("bad", [0, 9])
def test_supersample_out_of_range_is_refused(bad):
    with pytest.raises(ConfigError, match=r"render\.supersample"):
        _scene(0.0625, bad)
