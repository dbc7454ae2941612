"""The records a session archive stores: frame formats, steps, frames and events.

Plain frozen dataclasses with a lossless JSON form (``to_json`` / ``from_json``):
the archive's journal stores them as JSON lines, so they must survive a round
trip exactly (floats are written with ``repr`` precision).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rig.archive._errors import ArchiveError

__all__ = [
    "FRAME_DTYPES",
    "Event",
    "FrameFlag",
    "FrameFormat",
    "FrameInfo",
    "FrameRecord",
    "StepRecord",
    "json_safe",
]

#: Pixel types a camera may deliver.
FRAME_DTYPES = ("uint8", "uint16", "float32")


def json_safe(value: Any, *, where: str) -> Any:
    """``value`` as plain JSON types (numpy arrays become nested lists).

    Raises ``ArchiveError`` naming ``where`` for what JSON cannot hold
    (NaN/inf, non-string keys, arbitrary objects).
    """

    def default(obj: Any) -> Any:
        if isinstance(obj, np.ndarray):
            return obj.tolist()
        if isinstance(obj, np.generic):
            return obj.item()
        if isinstance(obj, tuple | set | frozenset):
            return list(obj)
        raise TypeError(f"{type(obj).__name__} {obj!r} is not JSON-serialisable")

    try:
        return json.loads(json.dumps(value, default=default, allow_nan=False))
    except (TypeError, ValueError) as err:
        raise ArchiveError(
            f"{where}: cannot store {err}; use str/int/float/bool/None, lists, "
            "dicts with string keys and numpy arrays of finite numbers"
        ) from err


def _finite(value: float, *, where: str) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise ArchiveError(f"{where} = {value}: must be a finite number")
    return value


def _direction(value, *, where: str) -> tuple[float, float]:
    theta, phi = (_finite(v, where=where) for v in value)
    if not 0.0 <= theta <= 180.0:
        raise ArchiveError(f"{where} θ = {theta}°: must lie in [0, 180]")
    return theta, phi


def _ident(value, *, where: str) -> str | int | None:
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, int | np.integer) and not isinstance(value, bool):
        return int(value)
    raise ArchiveError(f"{where} = {value!r}: must be a str, an int or None")


@dataclass(frozen=True)
class FrameFormat:
    """The fixed image format of one camera.

    Frames are stored as ``(height, width, channels)`` arrays of ``dtype``.
    """

    height: int
    width: int
    channels: int = 3
    dtype: str = "uint8"

    def __post_init__(self) -> None:
        for name in ("height", "width", "channels"):
            value = getattr(self, name)
            if not isinstance(value, int | np.integer) or isinstance(value, bool) or value < 1:
                raise ArchiveError(f"FrameFormat.{name} = {value!r}: must be an int ≥ 1")
            object.__setattr__(self, name, int(value))
        problem = f"FrameFormat.dtype = {self.dtype!r}: must be one of {FRAME_DTYPES}"
        try:
            dtype = np.dtype(self.dtype)
        except TypeError as err:
            raise ArchiveError(problem) from err
        # Stored little-endian (the zarr ``bytes`` codec); a native dtype is expected here.
        if dtype.name not in FRAME_DTYPES or not dtype.isnative:
            raise ArchiveError(problem)
        dtype = dtype.name
        object.__setattr__(self, "dtype", dtype)

    @property
    def shape(self) -> tuple[int, int, int]:
        """``(height, width, channels)`` of one frame."""
        return (self.height, self.width, self.channels)

    @property
    def nbytes(self) -> int:
        """Uncompressed size of one frame in bytes."""
        return self.height * self.width * self.channels * np.dtype(self.dtype).itemsize

    def to_json(self) -> dict:
        return {"height": self.height, "width": self.width, "channels": self.channels,
                "dtype": self.dtype}  # fmt: skip

    @classmethod
    def from_json(cls, data: Mapping) -> FrameFormat:
        return cls(data["height"], data["width"], data["channels"], data["dtype"])


@dataclass(frozen=True)
class FrameFlag:
    """A frame that did not record the state its step meant (``rig.frame_check``).

    ``camera`` and ``sub`` name the frame; ``reason`` says what the devices read
    back instead; ``recaptured``: the frame was taken again and the archived one
    matches (True), or the archived frame is still the mismatched one (False:
    processing leaves it out).
    """

    camera: str
    sub: int
    reason: str
    recaptured: bool

    def __post_init__(self) -> None:
        if not isinstance(self.camera, str) or not self.camera:
            raise ArchiveError(f"FrameFlag.camera = {self.camera!r}: must be a camera name")
        if not isinstance(self.sub, int | np.integer) or isinstance(self.sub, bool) or self.sub < 0:
            raise ArchiveError(f"FrameFlag.sub = {self.sub!r}: must be an int ≥ 0")
        object.__setattr__(self, "sub", int(self.sub))
        if not isinstance(self.reason, str) or not self.reason:
            raise ArchiveError(f"FrameFlag.reason = {self.reason!r}: must say why")
        object.__setattr__(self, "recaptured", bool(self.recaptured))

    def to_json(self) -> dict:
        return {"camera": self.camera, "sub": self.sub, "reason": self.reason,
                "recaptured": self.recaptured}  # fmt: skip

    @classmethod
    def from_json(cls, data: Mapping) -> FrameFlag:
        return cls(data["camera"], data["sub"], data["reason"], data["recaptured"])


@dataclass(frozen=True)
class StepRecord:
    """One step of a session: where the rig stood and what it captured.

    Parameters
    ----------
    index : int
        Step index in the compiled plan, ≥ 0; unique within a session.
    kind : str
        What the step captures: ``"btf"``, ``"ps"``, ``"mdf"``, ``"calibration"``…
    cameras : tuple of str
        Cameras whose frames belong to this step.
    views_deg : mapping camera → (θ, φ)
        View direction of each camera in the sample frame, degrees.
    light_deg : (θ, φ) or None
        Light direction in the sample frame, degrees; None when no lamp is lit.
    actuators : mapping axis → float
        Actuator positions (units as the axis name says, e.g. ``turntable_deg``).
    exposures_s : tuple of float
        Exposure time(s) in seconds; several for an HDR bracket.
    lamp, laser : str, int or None
        Id of the lit lamp and of the laser source, if any.
    started_at : float
        Time (s) the step started on the session's clock: monotonic seconds on a
        rig, virtual seconds in the simulator; replay paces steps by its differences.
    committed_at : float or None
        Unix time (s) of the commit; set by the archive, None before.
    flags : tuple of FrameFlag
        The step's frames that did not match the state it meant, re-captured or
        not (archive format 2; a format-1 archive reads as none).
    """

    index: int
    kind: str
    cameras: tuple[str, ...]
    views_deg: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    light_deg: tuple[float, float] | None = None
    actuators: Mapping[str, float] = field(default_factory=dict)
    exposures_s: tuple[float, ...] = ()
    lamp: str | int | None = None
    laser: str | int | None = None
    started_at: float = 0.0
    committed_at: float | None = None
    flags: tuple[FrameFlag, ...] = ()

    def __post_init__(self) -> None:
        where = f"step {self.index}"
        if not isinstance(self.index, int | np.integer) or isinstance(self.index, bool):
            raise ArchiveError(f"StepRecord.index = {self.index!r}: must be an int ≥ 0")
        if self.index < 0:
            raise ArchiveError(f"StepRecord.index = {self.index}: must be ≥ 0")
        object.__setattr__(self, "index", int(self.index))
        if not isinstance(self.kind, str) or not self.kind:
            raise ArchiveError(f"{where}: kind = {self.kind!r}: must be a non-empty str")
        cameras = (self.cameras,) if isinstance(self.cameras, str) else tuple(self.cameras)
        if not cameras or len(set(cameras)) != len(cameras):
            raise ArchiveError(f"{where}: cameras = {cameras!r}: must be distinct names, ≥ 1")
        object.__setattr__(self, "cameras", cameras)
        views = {}
        for camera, direction in dict(self.views_deg).items():
            if camera not in cameras:
                raise ArchiveError(
                    f"{where}: views_deg names camera {camera!r}, not one of {cameras}"
                )
            views[camera] = _direction(direction, where=f"{where}: views_deg[{camera!r}]")
        object.__setattr__(self, "views_deg", views)
        if self.light_deg is not None:
            light = _direction(self.light_deg, where=f"{where}: light_deg")
            object.__setattr__(self, "light_deg", light)
        actuators = {
            str(axis): _finite(value, where=f"{where}: actuators[{axis!r}]")
            for axis, value in dict(self.actuators).items()
        }
        object.__setattr__(self, "actuators", actuators)
        exposures = tuple(_finite(e, where=f"{where}: exposures_s") for e in self.exposures_s)
        if any(e <= 0 for e in exposures):
            raise ArchiveError(f"{where}: exposures_s = {exposures}: each must be > 0")
        object.__setattr__(self, "exposures_s", exposures)
        object.__setattr__(self, "lamp", _ident(self.lamp, where=f"{where}: lamp"))
        object.__setattr__(self, "laser", _ident(self.laser, where=f"{where}: laser"))
        object.__setattr__(
            self, "started_at", _finite(self.started_at, where=f"{where}: started_at")
        )
        if self.committed_at is not None:
            committed = _finite(self.committed_at, where=f"{where}: committed_at")
            object.__setattr__(self, "committed_at", committed)
        flags = tuple(self.flags)
        for flag in flags:
            if not isinstance(flag, FrameFlag) or flag.camera not in cameras:
                raise ArchiveError(
                    f"{where}: flags holds {flag!r}; expected FrameFlags of cameras {cameras}"
                )
        object.__setattr__(self, "flags", flags)

    def excluded(self, camera: str) -> frozenset[int]:
        """Subs of ``camera``'s frames still mismatched: what processing leaves out."""
        return frozenset(f.sub for f in self.flags if f.camera == camera and not f.recaptured)

    def to_json(self) -> dict:
        return {
            "index": self.index,
            "kind": self.kind,
            "cameras": list(self.cameras),
            "views_deg": {c: list(v) for c, v in self.views_deg.items()},
            "light_deg": None if self.light_deg is None else list(self.light_deg),
            "actuators": dict(self.actuators),
            "exposures_s": list(self.exposures_s),
            "lamp": self.lamp,
            "laser": self.laser,
            "started_at": self.started_at,
            "committed_at": self.committed_at,
            "flags": [f.to_json() for f in self.flags],
        }

    @classmethod
    def from_json(cls, data: Mapping) -> StepRecord:
        return cls(
            index=data["index"],
            kind=data["kind"],
            cameras=tuple(data["cameras"]),
            views_deg={c: tuple(v) for c, v in data["views_deg"].items()},
            light_deg=None if data["light_deg"] is None else tuple(data["light_deg"]),
            actuators=data["actuators"],
            exposures_s=tuple(data["exposures_s"]),
            lamp=data["lamp"],
            laser=data["laser"],
            started_at=data["started_at"],
            committed_at=data["committed_at"],
            flags=tuple(FrameFlag.from_json(f) for f in data.get("flags", ())),
        )


@dataclass(frozen=True, eq=False)
class FrameRecord:
    """One frame handed to the archive.

    Parameters
    ----------
    image : (H, W, C) or (H, W) ndarray
        Pixels in the camera's ``FrameFormat`` (``(H, W)`` only when C = 1).
    sub : int
        Sub-index within the step and camera: bracket member or scan frame, ≥ 0.
    exposure_s : float
        Exposure time, s.
    timestamp : float
        Unix time (s) the frame was exposed.
    """

    image: np.ndarray
    sub: int = 0
    exposure_s: float = 0.0
    timestamp: float = 0.0


@dataclass(frozen=True)
class FrameInfo:
    """Where a committed frame sits: one row of the frame table."""

    step: int
    camera: str
    sub: int
    exposure_s: float
    timestamp: float
    position: int


@dataclass(frozen=True)
class Event:
    """One entry of the archive's append-only event log.

    ``seq`` counts from 0 over the life of the archive, across reopenings;
    ``time`` is Unix time in seconds; ``payload`` holds plain JSON values.
    """

    seq: int
    time: float
    kind: str
    payload: Mapping[str, Any]
