"""Points on a ball's outline, searched along lines across where it is
expected (part of :mod:`calibration.lamps`)."""

from __future__ import annotations

from typing import Literal

import numpy as np
from scipy import ndimage

from rig.errors import RigError

Polarity = Literal["auto", "dark", "bright"]

_LEVEL_PX = 3.0  # the levels either side of an outline are read this far from it
_STEP_PX = 0.25  # sampling step along a search line


class LampCalibrationError(RigError):
    """The images cannot give a trustworthy lamp direction or position."""


def sphere_silhouette(
    image,
    outline_px,
    *,
    search_px: float = 4.0,
    min_contrast: float = 0.25,
    polarity: Polarity = "auto",
) -> np.ndarray:
    """Sub-pixel points on the outline of a ball against its background.

    Each expected outline point gives a search line from the outline's centroid
    through it. Along the line the outline is where the profile changes most
    steeply (rising outwards for a dark ball, falling for a bright one) within
    ± ``search_px`` of the expected point. A line whose step is below
    ``min_contrast`` × the 90th percentile of all steps (the background as
    bright as the ball there), or below 10 × the image noise, gives no point.

    Parameters
    ----------
    image : (H, W) or (H, W, C) linear values, any real dtype
    outline_px : (n, 2) float, x, y where the outline is expected (e.g. the
        projection of the sphere at its nominal place), in order around it
    search_px : how far the outline may lie from where it is expected
    polarity : ``"dark"`` (a ball darker than its background), ``"bright"``,
        or ``"auto"``: whichever the levels 3 px inside and outside the
        expected outline say

    Returns
    -------
    (m, 2) float64, x, y of the points found, m ≤ n
    """
    img = grey(image, "image")
    expected = np.asarray(outline_px, dtype=np.float64).reshape(-1, 2)
    centre = expected.mean(axis=0)
    radius = np.linalg.norm(expected - centre, axis=1)
    if len(expected) < 3 or not np.all(radius > 0) or not search_px > 0:
        raise LampCalibrationError(
            f"sphere_silhouette: need ≥ 3 distinct outline points and search_px > 0, got "
            f"{len(expected)} points and search_px={search_px}"
        )
    if polarity not in ("auto", "dark", "bright"):
        raise LampCalibrationError(
            f"sphere_silhouette: polarity={polarity!r}; valid are 'auto', 'dark', 'bright'"
        )
    toward = (expected - centre) / radius[:, None]
    reach = search_px + _LEVEL_PX
    offsets = np.arange(-reach, reach + _STEP_PX / 2, _STEP_PX)
    r = np.clip(radius[:, None] + offsets[None, :], 0.0, None)
    xs, ys = centre[0] + r * toward[:, :1], centre[1] + r * toward[:, 1:]
    profile = ndimage.map_coordinates(img, [ys.ravel(), xs.ravel()], order=1, mode="nearest")
    profile = profile.reshape(r.shape)
    if polarity == "bright" or (
        polarity == "auto" and np.median(profile[:, 0]) > np.median(profile[:, -1])
    ):
        profile = -profile  # a bright ball: the same search for a rising edge
    lag, level = round(1 / _STEP_PX), round(_LEVEL_PX / _STEP_PX)
    rise = np.full(r.shape, -np.inf)
    rise[:, lag:-lag] = profile[:, 2 * lag :] - profile[:, : -2 * lag]
    rise[:, np.abs(offsets) > search_px] = -np.inf
    peak = np.argmax(rise, axis=1)
    rows = np.arange(len(r))
    inner, outer = profile[rows, peak - level], profile[rows, peak + level]
    contrast = outer - inner
    # Pixel-to-pixel differences along the lines are mostly noise (an edge is a
    # few of them): a rise must stand well above it.
    steps = profile[:, lag:] - profile[:, :-lag]
    noise = 1.4826 * np.median(np.abs(steps)) / np.sqrt(2)
    strong = (contrast > 10 * noise) & (contrast >= min_contrast * np.percentile(contrast, 90))
    # The edge's place from the dark area under the profile between the two
    # levels (a step at e leaves e − r₀ of it): unlike a halfway crossing it
    # does not depend on how the pixel grid cuts the edge.
    window = peak[:, None] + np.arange(-level, level + 1)[None, :]
    seg = profile[rows[:, None], window]
    span = np.where(strong, contrast, 1.0)[:, None]
    dark = np.clip((outer[:, None] - seg) / span, 0.0, 1.0)
    area = (dark.sum(axis=1) - 0.5 * (dark[:, 0] + dark[:, -1])) * _STEP_PX
    r_edge = r[rows, peak - level] + area
    points = centre + r_edge[:, None] * toward
    return points[strong]


def grey(image, name: str) -> np.ndarray:
    img = np.asarray(image, dtype=np.float64)
    if img.ndim == 3:
        img = img.mean(axis=-1)
    if img.ndim != 2 or not np.all(np.isfinite(img)):
        raise LampCalibrationError(f"{name}: expected finite (H, W[, C]), got {np.shape(image)}")
    return img
