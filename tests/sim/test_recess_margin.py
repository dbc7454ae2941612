"""The holder's recess reaches past the measured square, so a map's border texels show the
sample as its interior does (not the recess walls, their shadows or the gap at them).

With the recess wall on the square's edge, the VirTex stage's frames rectified onto the
texel grid had edge texels in the wall's shadow under the lamps behind it (0 against
0.07–0.14 inside for the truth at θ = 60°), so photometric stereo tilted the edge normals by
up to 31° and darkened the albedo's edge columns to 190 against 216 (8-bit preview scale):
a line at every tile boundary of a render.
"""

import tomllib
from pathlib import Path

import numpy as np
import pytest

from processing.registration import register_frame
from rig.errors import ConfigError
from sim.scene import scene_from_dict
from sim.simulator import Simulator

VIRTEX = Path(__file__).parents[2] / "examples" / "scenes" / "virtex.toml"


def _scene(**sample):
    data = tomllib.loads(VIRTEX.read_text())
    data["sample"].update(sample)
    return scene_from_dict(data, base_dir=VIRTEX.parent)


def _edges_and_inner(texture: np.ndarray) -> tuple[np.ndarray, tuple[float, float]]:
    """Mean of the first and last rows and columns, and the range of the other rows' and
    columns' means (two texels in, out of the edges' own reach)."""
    grey = texture.mean(axis=-1)
    rows, cols = grey.mean(axis=1), grey.mean(axis=0)
    inner = np.concatenate([rows[2:-2], cols[2:-2]])
    return np.array([rows[0], rows[-1], cols[0], cols[-1]]), (inner.min(), inner.max())


def _within(edges, inner, slack):
    low, high = inner
    return bool(np.all((edges >= low - slack) & (edges <= high + slack)))


@pytest.mark.parametrize("light_deg", [(60.0, 0.0), (60.0, 90.0), (60.0, 200.0), (75.0, 300.0)])
def test_the_truths_border_texels_are_the_samples(light_deg):
    """The ray-cast BTF on the texel grid, the sample's bumps under a light from every side."""
    with Simulator(_scene()) as sim:
        truth = sim.btf_truth((0.0, 0.0), light_deg, 64)
    edges, inner = _edges_and_inner(truth)
    assert _within(edges, inner, 0.02 * truth.mean())


def test_the_measured_normtextures_border_texels_are_the_samples():
    """Each lamp's frame of the VirTex stage, registered onto the 64² texel grid (the frames
    its photometric stereo solves from): border rows and columns within the interior's."""
    scene = _scene()
    with Simulator(scene) as sim:
        camera = scene.rig.camera_model("cam0")
        for lamp in [f"lamp{i}" for i in range(6)]:
            frame = sim.render_state("cam0", lamps_on=[lamp])
            registration = register_frame(frame.image, scene.rig.holder, size=64, camera=camera)
            assert registration.valid
            texture = registration.normtexture.texture
            edges, inner = _edges_and_inner(texture)
            assert _within(edges, inner, 0.03 * texture.mean()), (lamp, edges, inner)


def test_a_recess_over_the_markers_is_refused():
    with pytest.raises(ConfigError, match=r"sample\.margin_mm"), Simulator(_scene(margin_mm=20.0)):
        pass
