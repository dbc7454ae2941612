"""The ``live`` group of a material: what the workers computed while a session ran.

``live/<stage>/<camera>/`` holds ``step`` and ``sub`` (n,) int64 — the frames
the stage returned results for, ordered by step and sub — and each array the
stage returned, stacked over those frames: ``(n, *shape)``. Version 0 is the
same layout without ``format``/``version``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from rig.material._errors import MaterialError
from rig.material._groups import check_version, format_attrs, read_arrays, require_arrays

__all__ = ["LiveResults", "read_live", "write_live"]

VERSION = 1


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


def write_live(group, results: Iterable[tuple[Mapping, Mapping[str, np.ndarray]]]) -> None:
    """Write the workers' results into the empty zarr ``group`` (the material's ``live``).

    ``results``: one ``(header, arrays)`` per processed frame, the header with
    ``step``, ``sub`` and ``camera``; arrays named ``<stage>.<name>`` (one
    frame may carry several stages). Every frame of a stage and camera must
    return the same names.
    """
    rows: dict[tuple[str, str], list[tuple[Mapping, dict]]] = {}
    for header, arrays in results:
        by_stage: dict[str, dict] = {}
        for full, value in arrays.items():
            stage, dot, name = full.partition(".")
            if not dot or not stage or not name:
                raise MaterialError(f"live result {full!r}: name it '<stage>.<array>'")
            by_stage.setdefault(stage, {})[name] = value
        for stage, values in by_stage.items():
            rows.setdefault((stage, str(header["camera"])), []).append((header, values))
    for (stage, camera), mine in sorted(rows.items()):
        mine.sort(key=lambda r: (r[0]["step"], r[0]["sub"]))
        names = set(mine[0][1])
        for header, values in mine:
            if set(values) != names:
                raise MaterialError(
                    f"live/{stage}/{camera}: step {header['step']} sub {header['sub']} returned "
                    f"{sorted(values)}, the stage's other frames {sorted(names)}"
                )
        sub = group.require_group(stage).create_group(camera)
        sub.create_array("step", data=np.array([r[0]["step"] for r in mine], dtype=np.int64))
        sub.create_array("sub", data=np.array([r[0]["sub"] for r in mine], dtype=np.int64))
        for name in sorted(names):
            stacked = _stack(name, [np.asarray(r[1][name]) for r in mine], f"live/{stage}")
            sub.create_array(name, data=stacked)
    group.attrs.update(format_attrs("live", VERSION))


def read_live(group, *, where: str = "material/live") -> dict[str, dict[str, LiveResults]]:
    """The ``live`` group (version 0 or 1): stage → camera → results."""
    check_version(dict(group.attrs), "live", (0, VERSION), where=where)
    out: dict[str, dict[str, LiveResults]] = {}
    for stage, stage_group in sorted(group.groups()):
        for camera, camera_group in sorted(stage_group.groups()):
            here = f"{where}/{stage}/{camera}"
            arrays = read_arrays(camera_group)
            require_arrays(arrays, ("step", "sub"), where=here)
            step, sub = arrays.pop("step"), arrays.pop("sub")
            for name, value in arrays.items():
                if value.shape[:1] != step.shape:
                    raise MaterialError(
                        f"{here}: {name} has {value.shape[:1]} rows, step has {step.shape}"
                    )
            out.setdefault(stage, {})[camera] = LiveResults(stage, camera, step, sub, arrays)
    return out


def _stack(name: str, values: list[np.ndarray], where: str) -> np.ndarray:
    shapes = {v.shape for v in values}
    if len(shapes) != 1:
        raise MaterialError(f"{where}: {name} has shapes {sorted(shapes)}; one per stage")
    return np.stack(values)
