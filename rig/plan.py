"""Measurement plans: what to capture, read from TOML and validated.

A plan names the sample, what to capture (``btf``, ``ps``, ``mdf``), the
exposures and HDR brackets, the resolution and where the archive goes. Every
problem in a plan is reported at once, one line each, naming the field, the
value and what would be valid.

Example
-------
>>> plan = parse_plan('''
... [sample]
... name = "corduroy"
... [captures.btf]
... views = "H2"
... lights = "H2"
... ''')
>>> len(plan.captures.btf.views.resolve())
81
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated

import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from rig.errors import ConfigError, PlanError
from rig.geometry import Sampling
from rig.tomlfile import file_text, format_validation_error, toml_data

__all__ = [
    "BtfCapture",
    "Captures",
    "Exposure",
    "MdfCapture",
    "Output",
    "Plan",
    "PsCapture",
    "Resolution",
    "Ring",
    "Sample",
    "SamplingSpec",
    "load_plan",
    "parse_plan",
]


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Ring(_Closed):
    """``count`` directions at one polar angle, equally spaced in azimuth
    (the photometric-stereo layout of seed 004: 3 lights 120° apart)."""

    theta_deg: float = Field(ge=0, le=89)
    count: int = Field(ge=1, le=360)
    phi0_deg: float = 0.0


def _sampling_spec(value):
    # Accept "H2", [[θ, φ], …] or {theta_deg, count}; normalise to a dict.
    if isinstance(value, str):
        return {"named": value}
    if isinstance(value, list):
        return {"directions": value}
    return value


class _SamplingSpec(_Closed):
    named: str | None = None
    directions: list[tuple[float, float]] | None = None
    ring: Ring | None = None

    @model_validator(mode="before")
    @classmethod
    def _ring_shorthand(cls, data):
        if isinstance(data, dict) and "theta_deg" in data:
            return {"ring": data}
        return data

    @model_validator(mode="after")
    def _one_kind(self) -> _SamplingSpec:
        given = [k for k in ("named", "directions", "ring") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(
                "give a sampling as a name ('H1' or 'H2'), a list of [theta_deg, phi_deg] "
                "pairs, or a ring {theta_deg, count}"
            )
        try:
            self.resolve()
        except ConfigError as err:
            raise ValueError(str(err)) from None
        return self

    def resolve(self) -> Sampling:
        if self.named is not None:
            return Sampling.named(self.named)
        if self.directions is not None:
            return Sampling("custom", np.array(self.directions, dtype=np.float64).reshape(-1, 2))
        ring = self.ring
        phis = ring.phi0_deg + np.arange(ring.count) * 360.0 / ring.count
        return Sampling(
            f"ring{ring.theta_deg:g}x{ring.count}",
            np.column_stack([np.full(ring.count, ring.theta_deg), phis]),
        )


SamplingSpec = Annotated[_SamplingSpec, BeforeValidator(_sampling_spec)]


class Sample(_Closed):
    name: str = Field(description="used in file names")
    description: str = ""

    @field_validator("name")
    @classmethod
    def _file_safe(cls, value: str) -> str:
        if not re.fullmatch(r"[A-Za-z0-9._-]{1,120}", value):
            raise ValueError(
                "use 1–120 letters, digits, '.', '_' or '-' (the name goes into file names)"
            )
        return value


class BtfCapture(_Closed):
    """Every (view, light) pair of two samplings (seed 000 §3.1)."""

    views: SamplingSpec
    lights: SamplingSpec


class PsCapture(_Closed):
    """Photometric stereo: a few views, each under a set of lights (seed 004)."""

    views: SamplingSpec = Field(default_factory=lambda: _SamplingSpec(directions=[(0.0, 0.0)]))
    lights: SamplingSpec

    @field_validator("lights")
    @classmethod
    def _at_least_three(cls, value: _SamplingSpec) -> _SamplingSpec:
        n = len(value.resolve())
        if n < 3:
            raise ValueError(f"photometric stereo needs at least 3 lights, got {n}")
        return value


class MdfCapture(_Closed):
    """Laser scans of each view from several laser source locations (seed 001 §3)."""

    views: SamplingSpec
    laser_locations: SamplingSpec
    scan_step_deg: float = Field(
        0.1, ge=0.001, le=10,
        description="sheet tilt between frames, spread over the whole sweep; a step finer than "
        "laser.sweep_speed_deg_s / laser.frame_rate_hz is taken at the frame rate",
    )  # fmt: skip


class FixedShot(_Closed):
    """Frames at given actuator positions, under one lamp: what calibration
    sessions need where a direction pair cannot say it (a zenith camera's view
    is the same at every turntable angle)."""

    turntable_deg: float = Field(ge=-720, le=720)
    arc_deg: float = Field(0.0, ge=-720, le=720)
    lamp: str = Field(description="a lamp id of the rig")
    cameras: tuple[str, ...] | None = Field(None, description="camera ids (default: all)")


class Captures(_Closed):
    btf: BtfCapture | None = None
    ps: PsCapture | None = None
    mdf: MdfCapture | None = None
    fixed: tuple[FixedShot, ...] | None = Field(None, min_length=1)

    @model_validator(mode="after")
    def _something(self) -> Captures:
        if all(getattr(self, k) is None for k in ("btf", "ps", "mdf", "fixed")):
            raise ValueError(
                "a plan must capture something: add [captures.btf], .ps, .mdf or .fixed"
            )
        return self


class Exposure(_Closed):
    exposure_s: float = Field(0.02, gt=0, le=60)
    hdr_brackets: tuple[float, ...] = Field(
        (1.0,), min_length=1, max_length=16, description="exposure multipliers"
    )
    laser_exposure_s: float = Field(0.005, gt=0, le=1)
    gain_db: float = Field(0.0, ge=0, le=48)

    @field_validator("hdr_brackets")
    @classmethod
    def _positive_distinct(cls, value: tuple[float, ...]) -> tuple[float, ...]:
        if any(m <= 0 for m in value):
            raise ValueError(f"every bracket multiplier must be > 0, got {list(value)}")
        if len(set(value)) != len(value):
            raise ValueError(f"bracket multipliers must be distinct, got {list(value)}")
        return value


class Resolution(_Closed):
    """Frames are read at ``scale`` × the camera's native size (binning/ROI)."""

    scale: float = Field(1.0, gt=0, le=1)


class Output(_Closed):
    archive: str = Field("sessions/{sample}.zarr", description="{sample} is replaced")

    @field_validator("archive")
    @classmethod
    def _only_sample_placeholder(cls, value: str) -> str:
        if "\x00" in value:
            raise ValueError("holds a NUL byte, which no path can hold")
        try:
            value.format(sample="sample")
        except KeyError as err:
            problem = f"unknown placeholder {{{err.args[0]}}}"
        except (AttributeError, IndexError, ValueError) as err:
            problem = str(err)
        else:
            return value
        raise ValueError(
            f"{problem}; the only placeholder is {{sample}} (write {{{{ or }}}} for a brace)"
        )


class Plan(_Closed):
    sample: Sample
    captures: Captures
    exposure: Exposure = Exposure()
    resolution: Resolution = Resolution()
    output: Output = Output()

    def archive_path(self) -> Path:
        return Path(self.output.archive.format(sample=self.sample.name))


def parse_plan(text: str, *, source: str = "<plan>") -> Plan:
    """Validate plan TOML text; a bad plan raises ``PlanError`` listing every problem."""
    try:
        data = toml_data(text)
    except ValueError as err:
        raise PlanError(source, [f"the plan {err}"]) from None
    try:
        return Plan.model_validate(data)
    except ValidationError as err:
        raise PlanError(source, format_validation_error(source, err, Plan)) from err


def load_plan(path: str | Path) -> Plan:
    """Read and validate a plan TOML file."""
    path = Path(path)
    try:
        text = file_text(path)
    except ValueError as err:
        raise PlanError(str(path), [f"the file {err}"]) from None
    return parse_plan(text, source=str(path))
