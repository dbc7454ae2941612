"""Camera.pixel_rays against the projection the renderer draws with."""

import numpy as np
import pytest

from render import Camera


@pytest.mark.parametrize(
    "camera",
    [
        Camera.perspective((30, -80, 60), (5, 0, 0), fov_deg=40, size=(64, 48)),
        Camera.orthographic((-20, -50, 70), (0, 3, 0), height=90.0, size=(48, 64)),
    ],
    ids=["perspective", "orthographic"],
)
def test_each_ray_passes_through_what_its_pixel_shows(camera):
    rng = np.random.default_rng(1)
    points = rng.uniform(-30, 30, (200, 3))
    near, far = camera.depth_range((0, 0, 0), 80.0)
    clip = np.c_[points, np.ones(len(points))] @ (
        camera.projection_matrix(near, far) @ camera.view_matrix()
    ).T.astype(np.float64)
    ndc = clip[:, :2] / clip[:, 3:]
    width, height = camera.size
    col = (ndc[:, 0] + 1) / 2 * width
    row = (1 - ndc[:, 1]) / 2 * height  # image row 0 at the top
    inside = (col >= 0) & (col < width) & (row >= 0) & (row < height)
    origins, directions = camera.pixel_rays()
    assert origins.shape == directions.shape == (height, width, 3)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=-1), 1.0, rtol=1e-12)
    # Each point lies on the ray of the pixel it projects into, within half a pixel.
    r, c = row[inside].astype(int), col[inside].astype(int)
    offset = points[inside] - origins[r, c]
    along = np.sum(offset * directions[r, c], axis=1)
    miss = np.linalg.norm(offset - along[:, None] * directions[r, c], axis=1)
    pixel = (
        camera.height
        if camera.fov_deg is None
        else 2 * along * np.tan(np.deg2rad(camera.fov_deg) / 2)
    ) / height
    assert np.all(miss <= 0.75 * pixel)
    assert inside.sum() > 50
