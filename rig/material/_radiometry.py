"""Which radiometric corrections processing applied to a material's frames, and from where.

The ``btf`` group and each ``ps`` view record it in the attribute ``radiometry``
(from version 2): the cameras whose frames the archive's response curve
linearised, the lamps whose frames their flat-field map divided, the
calibration version and the calibration sessions they came from, and what was
left uncorrected with the reason (``rig process --raw``, a camera without a
curve…). Groups of earlier versions were written before any correction was
applied: they read as :data:`NOT_RECORDED`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from rig.material._errors import MaterialError

__all__ = ["NOT_RECORDED", "Radiometry"]


@dataclass(frozen=True)
class Radiometry:
    """The radiometric corrections behind a material's values.

    Attributes
    ----------
    linearised : tuple of str
        Cameras whose frames were linearised by their response curve.
    flat_fielded : tuple of str
        Lamps whose frames were divided by their flat-field map (on the texel grid).
    calibration_version : int
        The archive's calibration version the corrections came from (0: none).
    sources : dict[str, str]
        ``"response"`` / ``"flat_field"`` → the calibration session and when it was measured;
        ``"irradiance"`` → where the near lamps stood for the per-texel irradiance (btf).
    skipped : dict[str, str]
        What was left uncorrected → why.
    """

    linearised: tuple[str, ...] = ()
    flat_fielded: tuple[str, ...] = ()
    calibration_version: int = 0
    sources: dict[str, str] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)

    @property
    def applied(self) -> bool:
        """True when any correction changed the frames."""
        return bool(self.linearised or self.flat_fielded)

    def to_attrs(self) -> dict[str, Any]:
        """The JSON-able ``radiometry`` attribute."""
        return {
            "linearised": list(self.linearised),
            "flat_fielded": list(self.flat_fielded),
            "calibration_version": int(self.calibration_version),
            "sources": dict(self.sources),
            "skipped": dict(self.skipped),
        }

    @classmethod
    def from_attrs(cls, value: Any, *, where: str) -> Radiometry:
        """The record of a ``radiometry`` attribute; MaterialError naming ``where`` otherwise."""
        keys = {"linearised", "flat_fielded", "calibration_version", "sources", "skipped"}
        if not isinstance(value, dict) or set(value) != keys:
            raise MaterialError(
                f"{where}: attribute radiometry = {value!r}; expected an object with {sorted(keys)}"
            )
        lists = [value["linearised"], value["flat_fielded"]]
        maps = [value["sources"], value["skipped"]]
        version = value["calibration_version"]
        if (
            not all(isinstance(v, list) and all(isinstance(s, str) for s in v) for v in lists)
            or not all(isinstance(m, dict) and all(isinstance(s, str) for s in m.values())
                       for m in maps)
            or not isinstance(version, int) or version < 0
        ):  # fmt: skip
            raise MaterialError(
                f"{where}: attribute radiometry = {value!r}; linearised and flat_fielded are "
                "lists of ids, sources and skipped map names to text, calibration_version ≥ 0"
            )
        return cls(tuple(lists[0]), tuple(lists[1]), version, dict(maps[0]), dict(maps[1]))


#: What a group written before corrections were recorded (ps/btf version ≤ 1) reads as.
NOT_RECORDED = Radiometry(
    skipped={"all": "written before processing applied radiometric corrections: frames as recorded"}
)
