"""Synthetic data sets in the UBO2003 layout, generated here (a few views × lights, 32²)."""

from pathlib import Path

import cv2
import numpy as np

from rig.geometry import direction_vector
from rig.interchange import to_srgb, ubo2003_file, ubo2003_view_folder

SIZE = 32
VIEWS = ((0.0, 0.0), (15.0, 60.0), (30.0, 90.0))
LIGHTS = ((0.0, 0.0), (30.0, 0.0), (30.0, 120.0), (30.0, 240.0), (60.0, 30.0))


def normtexture(view, light, size: int = SIZE) -> np.ndarray:
    """(size, size, 3) linear values in [0, 0.9]: a bumpy Lambertian texture, tinted by view."""
    y, x = np.mgrid[0:size, 0:size] / size
    normals = np.stack([0.4 * np.sin(6 * x), 0.4 * np.cos(5 * y), np.ones_like(x)], axis=-1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    shade = np.clip(normals @ direction_vector(*light), 0.0, None)
    tint = np.array([0.9, 0.7 - view[0] / 200, 0.5 + view[1] / 900])
    return (shade[..., None] * tint).astype(np.float32)


def write_ubo_folder(root: Path, views=VIEWS, lights=LIGHTS, *, skip=(), suffix=".png") -> Path:
    """A UBO2003 folder of 8-bit sRGB images; ``skip`` lists (view, light) pairs left out."""
    root.mkdir(parents=True)
    for view in views:
        folder = root / ubo2003_view_folder(view)
        folder.mkdir()
        for index, light in enumerate(lights):
            if (view, light) in skip:
                continue
            image = to_srgb(normtexture(view, light))
            cv2.imwrite(str(folder / ubo2003_file(index, light, view, suffix=suffix)),
                        np.ascontiguousarray(image[..., ::-1]))  # fmt: skip
    return root
