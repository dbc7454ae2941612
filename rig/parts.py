"""Parts every rig kind is built of: a rotary axis's motion limits, a lamp.

Lengths in mm, angles in degrees, times in seconds.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = ["Axis", "Lamp", "SignedPolar"]

SignedPolar = Annotated[float, Field(ge=-90, le=90, description="signed polar angle on an arc")]


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Axis(_Closed):
    """Motion limits and timing of one rotary axis (trapezoidal velocity profile)."""

    speed_deg_s: float = Field(gt=0, description="cruise speed")
    accel_deg_s2: float = Field(gt=0, description="acceleration and deceleration")
    settle_s: float = Field(0.2, ge=0, description="wait after the move before exposing")
    min_deg: float = 0.0
    max_deg: float = 360.0

    @model_validator(mode="after")
    def _range(self) -> Axis:
        if self.max_deg <= self.min_deg:
            raise ValueError(f"max_deg ({self.max_deg}) must exceed min_deg ({self.min_deg})")
        return self

    def move_time_s(self, delta_deg) -> np.ndarray:
        """Time of a point-to-point move of ``delta_deg`` (no settle), broadcast."""
        d = np.abs(np.asarray(delta_deg, dtype=np.float64))
        v, a = self.speed_deg_s, self.accel_deg_s2
        d_ramp = v * v / a  # distance spent accelerating and decelerating
        return np.where(d < d_ramp, 2.0 * np.sqrt(d / a), d / v + v / a)


class Lamp(_Closed):
    """One lamp: on a Wang rig's light arc at a signed polar angle; on the other
    kinds, placed by the kind's geometry (``theta_deg`` is then its polar angle)."""

    id: str
    theta_deg: SignedPolar
    kind: Literal["point", "spot", "directional"] = "point"
    intensity: float = Field(1.0, gt=0, description="relative radiant intensity")
    spot_cutoff_deg: float = Field(60.0, gt=0, le=90, description="spot lamps: half-angle")
