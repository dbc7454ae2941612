"""Light sources: point lights (with 1/r² fall-off) and directional lights.

Directions follow ``rig.geometry``: a light's direction points from the
surface towards the lamp. A light's contribution to a surface point is its
irradiance factor E = colour · intensity (÷ r² for a point light, r in scene
units) times the material's normtexture value for that light direction, which
already holds the cosine of the light's incidence (the normtextures were
measured under it); light from below a point's horizon adds nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from render._errors import RenderError

__all__ = ["MAX_LIGHTS", "DirectionalLight", "Light", "PointLight"]

#: Lights one frame can hold (the shader's fixed arrays).
MAX_LIGHTS = 8


#: Largest colour · intensity: times float16 texels (≤ 65504) and 8 lights, and
#: over the 1 µm² floor of a point light's r², the shader's float32 sums stay finite.
MAX_EMISSION = 1e20


def _checked(kind: str, colour, intensity) -> tuple[np.ndarray, float]:
    rgb = np.asarray(colour, dtype=np.float64)
    if rgb.shape != (3,) or not np.all(np.isfinite(rgb)) or np.any(rgb < 0):
        raise RenderError(f"{kind} colour = {colour!r}: expected three finite values ≥ 0 (r, g, b)")
    if not (np.isfinite(intensity) and intensity >= 0):
        raise RenderError(f"{kind} intensity = {intensity}: must be finite and ≥ 0")
    if float(rgb.max()) * intensity > MAX_EMISSION:
        raise RenderError(
            f"{kind} colour · intensity = {float(rgb.max()) * intensity:.3g}: at most "
            f"{MAX_EMISSION:.0e}"
        )
    return rgb, float(intensity)


@dataclass(frozen=True)
class PointLight:
    """A lamp at ``position`` (scene units); irradiance colour · intensity / r²."""

    position: tuple[float, float, float]
    colour: tuple[float, float, float] = (1.0, 1.0, 1.0)
    intensity: float = 1.0

    def __post_init__(self) -> None:
        p = np.asarray(self.position, dtype=np.float64)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise RenderError(f"point light position = {self.position!r}: expected (x, y, z)")
        _checked("point light", self.colour, self.intensity)

    @property
    def emission(self) -> np.ndarray:
        """colour · intensity, (3,) float64."""
        return np.asarray(self.colour, dtype=np.float64) * self.intensity


@dataclass(frozen=True)
class DirectionalLight:
    """A light at infinity in ``direction`` (towards the light); irradiance colour · intensity."""

    direction: tuple[float, float, float]
    colour: tuple[float, float, float] = (1.0, 1.0, 1.0)
    intensity: float = 1.0

    def __post_init__(self) -> None:
        d = np.asarray(self.direction, dtype=np.float64)
        if d.shape != (3,) or not np.all(np.isfinite(d)) or not np.linalg.norm(d) > 0:
            raise RenderError(
                f"directional light direction = {self.direction!r}: expected a non-zero (x, y, z) "
                "pointing towards the light"
            )
        _checked("directional light", self.colour, self.intensity)

    @property
    def unit_direction(self) -> np.ndarray:
        d = np.asarray(self.direction, dtype=np.float64)
        return d / np.linalg.norm(d)

    @property
    def emission(self) -> np.ndarray:
        """colour · intensity, (3,) float64."""
        return np.asarray(self.colour, dtype=np.float64) * self.intensity


Light = PointLight | DirectionalLight
