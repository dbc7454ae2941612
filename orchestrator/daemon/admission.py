"""What a session must pass before it starts: checks that cost little and touch nothing.

A plan small enough to compile while the daemon waits, an archive path that can
be created, and, for a resumed session, a rig config that describes the rig the
archive recorded (where each device is plugged in may change, what it is may not).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from pydantic import BaseModel, ValidationError

from orchestrator.wire.protocol import MAX_PLAN_PAIRS
from rig.archive import Archive, SessionFinished
from rig.config import RigConfig
from rig.errors import PlanError, RigError
from rig.plan import Plan
from rig.tomlfile import format_validation_error

__all__ = [
    "SessionError",
    "check_archive_place",
    "check_not_finished",
    "check_plan_size",
    "check_same_rig",
    "rig_config_from_toml",
    "rig_differences",
]

#: Models of the sections that may change between a crash and the resume: each role's
#: device section and each camera's connection (where and how a device is reached and wired).
_CONNECTIONS_MODULE = "rig.devices"
_NOT_GEOMETRY = frozenset({"calibration"})  # the archive keeps the calibration it began with


class SessionError(RigError):
    """A session cannot start or go on (bad archive, mismatching plan…); ``field`` names
    the control request's field at fault, where one is."""

    def __init__(self, message: str, *, field: str | None = None):
        super().__init__(message)
        self.field = field


def check_plan_size(plan: Plan, source: str) -> None:
    """Refuse a plan with more than ``MAX_PLAN_PAIRS`` (view, light) pairs: compiling it
    would keep the daemon from answering for minutes."""
    c = plan.captures
    pairs = len(c.fixed or ())
    for capture, second in ((c.ps, "lights"), (c.btf, "lights"), (c.mdf, "laser_locations")):
        if capture is not None:
            pairs += len(capture.views.resolve()) * len(getattr(capture, second).resolve())
    if pairs > MAX_PLAN_PAIRS:
        raise PlanError(
            source,
            [
                f"captures: {pairs} (view, light) pairs; the limit is {MAX_PLAN_PAIRS} "
                "per plan (split it into several sessions)"
            ],
        )


def check_archive_place(path: Path, field: str) -> None:
    """Refuse an archive path that exists, or whose nearest existing parent is a file."""
    if path.exists():
        raise SessionError(
            f"archive {path} already exists; choose a new path (or `rig resume` it)", field=field
        )
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise SessionError(
                    f"archive {path}: {parent} is a file, not a folder; choose a path in a folder",
                    field=field,
                )
            return


def check_not_finished(archive: Archive) -> None:
    """Refuse to resume an archive whose session finished."""
    try:
        archive.check_resumable()
    except SessionFinished as err:
        raise SessionError(str(err), field="args.archive") from None


def rig_config_from_toml(text: str, *, source: str) -> RigConfig:
    """A rig config sent as TOML text with a request (``args.config_toml``)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise SessionError(
            f"rig config {source} is not valid TOML: {err}", field="args.config_toml"
        ) from None
    try:
        return RigConfig.model_validate(data)
    except ValidationError as err:
        problems = "; ".join(format_validation_error(source, err, RigConfig))
        raise SessionError(
            f"rig config {source}: invalid: {problems}", field="args.config_toml"
        ) from None


def rig_differences(recorded: RigConfig, current: RigConfig) -> list[tuple[str, object, object]]:
    """``(field, recorded value, current value)`` for every field of the rig that differs,
    leaving out the device sections (ports, addresses, retries, wiring) and the calibration
    file."""
    return _differences(recorded, current, "")


def check_same_rig(recorded: RigConfig, current: RigConfig, *, source: str) -> None:
    """Refuse to continue ``source``'s session on a rig that is not the one it recorded."""
    changed = rig_differences(recorded, current)
    if changed:
        field, was, now = changed[0]
        more = f" (and {len(changed) - 1} more field(s))" if len(changed) > 1 else ""
        raise SessionError(
            f"{source}: the daemon's rig config differs from the recorded one in {field}: "
            f"recorded {was!r}, now {now!r}{more}; a session resumes only on the rig it "
            "began on (connections such as ports may change, geometry may not)"
        )


def _differences(a, b, path: str) -> list[tuple[str, object, object]]:
    if isinstance(a, BaseModel) and type(a) is type(b):
        if type(a).__module__ == _CONNECTIONS_MODULE:
            return []
        found = []
        for name in type(a).model_fields:
            if path == "" and name in _NOT_GEOMETRY:
                continue
            where = f"{path}.{name}" if path else name
            found += _differences(getattr(a, name), getattr(b, name), where)
        return found
    if isinstance(a, list | tuple) and isinstance(b, list | tuple) and len(a) == len(b):
        return [
            d
            for i, (x, y) in enumerate(zip(a, b, strict=True))
            for d in _differences(x, y, f"{path}[{i}]")
        ]
    return [] if a == b else [(path, a, b)]
