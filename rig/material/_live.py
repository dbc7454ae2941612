"""The ``live`` group of a material: what the workers computed while a session ran.

``live/<stage>/<camera>/`` holds ``step`` and ``sub`` (n,) int64 — the frames
the stage returned results for, in the order the results arrived — and each
array the stage returned, stacked over those frames: ``(n, *shape)``. Rows are
appended in batches, ``step`` last: a row exists once ``step`` has it, and rows
an interrupted batch left in the other arrays (beyond ``len(step)``) are not
read, and are cut off when the group is next appended to. Version 0 is the same
layout without ``format``/``version`` (and ordered by step).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from rig.material._errors import MaterialError
from rig.material._groups import check_version, format_attrs, read_arrays, require_arrays

__all__ = ["LiveAppender", "LiveResults", "live_rows", "read_live"]

VERSION = 1
_CHUNK_BYTES = 1 << 16  # rows per chunk: about this many bytes, at least one row


@dataclass(frozen=True)
class LiveResults:
    """One live stage's results for one camera.

    ``step``, ``sub`` (n,) int64: the frames; ``arrays``: each result the
    stage returned, (n, *shape), row i for frame (step[i], sub[i]).
    """

    stage: str
    camera: str
    step: np.ndarray
    sub: np.ndarray
    arrays: dict[str, np.ndarray]


def live_rows(
    header: Mapping, arrays: Mapping[str, np.ndarray]
) -> dict[tuple[str, str], dict[str, np.ndarray]]:
    """One frame's results as rows: (stage, camera) → ``{"step", "sub", name: array}``.

    ``header`` has the frame's ``step``, ``sub`` and ``camera``; ``arrays`` are
    named ``<stage>.<name>`` (one frame may carry several stages). The arrays
    are copied (a message buffer can go back to its socket).
    """
    ids = {"step": np.int64(header["step"]), "sub": np.int64(header["sub"])}
    rows: dict[tuple[str, str], dict[str, np.ndarray]] = {}
    for full, value in arrays.items():
        stage, dot, name = full.partition(".")
        if not dot or not stage or not name or name in ids:
            raise MaterialError(f"live result {full!r}: name it '<stage>.<array>'")
        rows.setdefault((stage, str(header["camera"])), dict(ids))[name] = np.array(value)
    return rows


class LiveAppender:
    """Appends rows to ``live/<stage>/<camera>`` of a writable ``material/`` zarr group.

    The ``live`` group is created (with its format and version) on the first
    append, so a session without results writes nothing.
    """

    def __init__(self, material):
        self._material = material
        self._live = None
        self._arrays: dict[tuple[str, str], dict] = {}

    def append(self, stage: str, camera: str, rows: list[dict[str, np.ndarray]]) -> None:
        """Append ``rows`` (from :func:`live_rows`) of one stage and camera.

        Every row has the same names, and each array the same shape as in the
        rows before (else MaterialError, naming them; nothing is appended).
        """
        where = f"live/{stage}/{camera}"
        names = rows[0].keys()
        for row in rows[1:]:
            if row.keys() != names:
                raise MaterialError(
                    f"{where}: step {row['step']} sub {row['sub']} returned {_names(row)}, "
                    f"step {rows[0]['step']} {_names(rows[0])}; a stage returns the same arrays "
                    "for every frame"
                )
        arrays = self._group(stage, camera, rows[0])
        stacked = {}
        for name in names:
            shapes = sorted({row[name].shape for row in rows} | {arrays[name].shape[1:]})
            if len(shapes) != 1:
                raise MaterialError(f"{where}: {name} has shapes {shapes}; one per stage")
            stacked[name] = np.stack([row[name] for row in rows])
        for name in (*(n for n in names if n not in ("sub", "step")), "sub", "step"):
            arrays[name].append(stacked[name])  # step last: the commit

    def _group(self, stage: str, camera: str, example: Mapping[str, np.ndarray]) -> dict:
        """The arrays of ``live/<stage>/<camera>``, created or cut back to ``len(step)``."""
        arrays = self._arrays.get((stage, camera))
        if arrays is None:
            if self._live is None:
                self._live = self._material.require_group("live")
                self._live.attrs.update(format_attrs("live", VERSION))
            group = self._live.require_group(stage).require_group(camera)
            arrays = dict(group.arrays())
            rows = arrays["step"].shape[0] if "step" in arrays else 0
            for array in arrays.values():
                if array.shape[0] != rows:  # a batch a crash interrupted
                    array.resize((rows, *array.shape[1:]))
            self._arrays[(stage, camera)] = arrays
        rows = arrays["step"].shape[0] if "step" in arrays else 0
        for name, value in example.items():
            if name not in arrays:  # a new array starts with zero rows for the older frames
                per_chunk = max(1, _CHUNK_BYTES // max(1, value.nbytes))
                arrays[name] = self._live[stage][camera].create_array(
                    name, shape=(rows, *value.shape), chunks=(per_chunk, *value.shape),
                    dtype=value.dtype,
                )  # fmt: skip
        return arrays


def read_live(group, *, where: str = "material/live") -> dict[str, dict[str, LiveResults]]:
    """The ``live`` group (version 0 or 1): stage → camera → results (complete rows only)."""
    check_version(dict(group.attrs), "live", (0, VERSION), where=where)
    out: dict[str, dict[str, LiveResults]] = {}
    for stage, stage_group in sorted(group.groups()):
        for camera, camera_group in sorted(stage_group.groups()):
            here = f"{where}/{stage}/{camera}"
            arrays = read_arrays(camera_group, where=here)
            require_arrays(arrays, ("step", "sub"), where=here)
            step = arrays.pop("step")
            rows = len(step)
            for name, value in arrays.items():
                if value.shape[0] < rows:
                    raise MaterialError(f"{here}: {name} has {value.shape[0]} rows, step {rows}")
            kept = {name: value[:rows] for name, value in arrays.items()}
            sub = kept.pop("sub")
            out.setdefault(stage, {})[camera] = LiveResults(stage, camera, step, sub, kept)
    return out


def _names(row: Mapping) -> list[str]:
    return sorted(n for n in row if n not in ("step", "sub"))
