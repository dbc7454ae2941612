"""Run processing stages over a recorded session archive on Dask.

A *stage* (see :class:`Stage`) splits an archive into independent work items
(``plan``), computes each item from the archive alone (``compute``, run on a
Dask worker: it opens the archive read-only itself, so a cluster with the
archive on a shared file system scales past one machine), and writes all item
results into the archive's ``material/<stage>`` group (``write``). The write
goes through ``Archive.replace_material``: re-running a stage replaces its
output atomically, and a failed run leaves the previous output intact.

No home-made scheduler: a ``distributed.LocalCluster`` by default (threads,
so numpy releases the GIL and nothing is pickled to subprocesses), or a
running scheduler's address.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from rig.archive import Archive
from rig.calfile import CalibrationFile
from rig.config import RigConfig
from rig.errors import ConfigError, RigError

__all__ = [
    "Stage",
    "StageFailed",
    "StageRun",
    "StageSkipped",
    "View",
    "archive_calibration",
    "calibrated_camera",
    "calibration_fit",
    "frame_camera",
    "run_stages",
    "views_of",
]

log = logging.getLogger(__name__)

#: progress(stage, items done, items in all)
Progress = Callable[[str, int, int], None]


class Stage(Protocol):
    """What ``rig process`` needs from a stage."""

    name: str

    def plan(self, archive: Archive) -> list[Any]:
        """The independent work items of this archive (small, plain values; ``str`` of
        one names it for the user, e.g. ``view cam0_tt000.0``)."""

    def compute(self, archive_path: str, item: Any) -> Any:
        """One item's result, from the archive at ``archive_path`` (opened read-only)."""

    def write(self, group, archive: Archive, results: Sequence[Any]) -> dict:
        """Write the results into ``group`` (``material/<name>``); a summary for the user.

        Raises ``StageSkipped`` when no item gave anything to write."""


class StageSkipped(RigError):
    """A stage could use none of its items (every frame flagged…); the message says
    why. The stage's previous output stays, and the other stages still run."""


@dataclass(frozen=True)
class View:
    """One camera at one turntable angle, and the steps of one kind captured from there."""

    name: str
    camera: str
    turntable_deg: float
    steps: tuple[int, ...]

    def __str__(self) -> str:
        return f"view {self.name}"


def views_of(archive: Archive, kind: str) -> list[View]:
    """The views of the archive's ``kind`` steps (ps: one lamp each; mdf: one scan each)."""
    views: dict[tuple[str, float], list[int]] = {}
    for step in archive.step_table():
        if step.kind != kind:
            continue
        turntable = round(float(step.actuators.get("turntable_deg", 0.0)), 1) % 360.0
        for camera in step.cameras:
            views.setdefault((camera, turntable), []).append(step.index)
    return [
        View(f"{camera}_tt{turntable:05.1f}", camera, turntable, tuple(steps))
        for (camera, turntable), steps in sorted(views.items())
    ]


def frame_camera(archive: Archive, config: RigConfig, camera_id: str, turntable_deg: float):
    """The model of ``camera_id``'s archived frames: sample frame at ``turntable_deg``,
    intrinsics scaled to the plan's resolution (the daemon bins frames by it).

    The archive's calibration (``rig calibrate``) when it has the camera, else
    the rig config's nominal model.
    """
    scale = float(archive.plan.get("resolution", {}).get("scale", 1.0))
    return calibrated_camera(
        config, archive_calibration(archive), camera_id, turntable_deg, scale=scale
    )


def archive_calibration(archive: Archive) -> CalibrationFile | None:
    """The archive's calibration, validated, as far as it is its rig's
    (:func:`calibration_fit`); None when it holds none or another rig's."""
    return calibration_fit(archive)[0]


def calibration_fit(archive: Archive) -> tuple[CalibrationFile | None, dict[str, str]]:
    """The archive's calibration as far as it fits the rig that recorded it, and what
    was left out → why (:meth:`CalibrationFile.fitted_to`); ``{"all": …}`` and None
    when the archive holds none."""
    if not archive.calibration:
        return None, {"all": "the archive holds no calibration"}
    source = f"{archive.path} (calibration v{archive.calibration_version})"
    calibration = CalibrationFile.from_dict(archive.calibration, source=source)
    return calibration.fitted_to(RigConfig.model_validate(archive.rig_config))


def calibrated_camera(
    config: RigConfig,
    calibration: CalibrationFile | None,
    camera_id: str,
    turntable_deg: float,
    *,
    scale: float,
):
    """A camera's calibrated model where ``calibration`` has it, else the nominal
    one; in the sample frame at ``turntable_deg``, for frames read at ``scale`` ×
    the camera's native size."""
    calibrated = calibration.camera(camera_id) if calibration is not None else None
    if calibrated is None:
        return config.camera_model(camera_id, turntable_deg=turntable_deg).scaled(scale)
    width = max(1, round(config.camera(camera_id).width * scale))
    return calibrated.model(turntable_deg=turntable_deg, scale=width / calibrated.image_size[0])


@dataclass(frozen=True)
class StageRun:
    """What one stage did; ``skipped``: why it wrote nothing (None when it did);
    ``absent``: the archive holds no captures of it (the plan asked for none), which is
    not a failure."""

    stage: str
    items: int
    summary: Mapping[str, Any]
    skipped: str | None = None
    absent: bool = False


def run_stages(
    archive_path: str | Path,
    stages: Sequence[Stage],
    *,
    scheduler: str | None = None,
    workers: int = 2,
    progress: Progress | None = None,
) -> list[StageRun]:
    """Run ``stages`` in order over the archive; their results land in ``material/``.

    Parameters
    ----------
    archive_path : path of a session archive (committed steps only are read)
    stages : the stages, e.g. ``[STAGES["ps"]]``
    scheduler : address of a running Dask scheduler (``tcp://host:8786``);
        default a local cluster of ``workers`` threads
    progress : called as items finish

    A stage that can use none of its items (``StageSkipped``) is reported in
    its ``StageRun.skipped``, and the stages after it still run. A stage the
    archive holds no captures for (a PS-only session asked for btf) is
    skipped too, with ``absent`` set, as long as another stage has work.

    Raises
    ------
    ConfigError
        No stage finds anything to do in this archive (e.g. no ps steps for
        ``ps``), or ``scheduler`` is not a scheduler address.
    RigError
        No scheduler answers at ``scheduler``; an item's error (``StageFailed``
        for one that is not btfrig's own names the stage and the item).
    """
    from distributed import LocalCluster, as_completed

    path = str(Path(archive_path).resolve())
    with Archive.open(path, mode="r") as archive:
        plans = {stage.name: stage.plan(archive) for stage in stages}
        captured = sorted(k for k, v in archive.plan.get("captures", {}).items() if v)
        kind = archive.rig_config.get("kind", "wang")
    absent = {
        stage.name: f"the archive has no {stage.name} captures: its plan captures "
        f"{', '.join(captured) or 'nothing'}, on a {kind!r} rig"
        for stage in stages if not plans[stage.name]
    }  # fmt: skip
    if len(absent) == len(stages):
        raise ConfigError(f"{path}: nothing to process; " + "; ".join(
            f"stage {name!r}: {why}" for name, why in absent.items()))  # fmt: skip
    cluster = None
    if scheduler is None:
        # The scheduler serves HTTP even without a dashboard, on 8787 unless told
        # otherwise, and warns when another cluster of the machine holds that port:
        # a free loopback port never collides.
        cluster = LocalCluster(
            n_workers=1, threads_per_worker=workers, processes=False,
            dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR,
        )  # fmt: skip
    runs = []
    worker_log = logging.getLogger("distributed.worker")
    worker_log.addFilter(_reported_here)
    try:
        with _client(cluster if cluster is not None else scheduler) as client:
            for stage in stages:
                if stage.name in absent:
                    runs.append(StageRun(stage.name, 0, {}, absent[stage.name], absent=True))
                    continue
                items = plans[stage.name]
                futures = [client.submit(stage.compute, path, item, pure=False) for item in items]
                index = {f.key: i for i, f in enumerate(futures)}
                results: list[Any] = [None] * len(items)
                if progress is not None:
                    progress(stage.name, 0, len(items))
                for done, future in enumerate(as_completed(futures), start=1):
                    item = index[future.key]
                    results[item] = _result(future, stage.name, items[item])
                    if progress is not None:
                        progress(stage.name, done, len(items))
                try:
                    with (
                        Archive.open(path, mode="a") as archive,
                        archive.replace_material(stage.name) as group,
                    ):
                        summary = stage.write(group, archive, results)
                except StageSkipped as skipped:
                    log.info("stage %s skipped: %s", stage.name, skipped)
                    runs.append(StageRun(stage.name, len(items), {}, skipped=str(skipped)))
                    continue
                except OSError as err:  # a full disk: replace_material kept the old result
                    raise StageFailed(
                        f"{path}/material/{stage.name}: writing the {stage.name} result failed: "
                        f"{err.strerror or err}; the previous result is unchanged (free space, "
                        "then run the stage again)"
                    ) from err
                log.info("stage %s: %d item(s) into material/", stage.name, len(items))
                runs.append(StageRun(stage.name, len(items), summary))
    finally:
        worker_log.removeFilter(_reported_here)
        if cluster is not None:
            cluster.close()
    return runs


class StageFailed(RigError):
    """An item of a stage raised an error that is not one of btfrig's (a bug, or data
    no check foresaw); the message names the stage, the item and the error."""


def _result(future, stage: str, item: Any) -> Any:
    """The result of ``item``'s future; what its worker raised as one named error
    (btfrig's own errors already name the file, step or view: they pass unchanged)."""
    try:
        return future.result()
    except RigError:
        raise
    except Exception as err:
        raise StageFailed(f"stage {stage}, {item}: {type(err).__name__}: {err}") from err


def _reported_here(record: logging.LogRecord) -> bool:
    """Drop a local worker's "Compute Failed" report: the item's error reaches the
    user once, from ``_result``, instead of as Dask's multi-line text."""
    return not str(record.msg).startswith("Compute Failed")


def _client(cluster_or_address):
    """A Dask client of a local cluster, or of the scheduler at an address."""
    from distributed import Client
    from distributed.comm import get_address_host_port

    if not isinstance(cluster_or_address, str):
        return Client(cluster_or_address)
    try:  # before a client starts its threads
        get_address_host_port(cluster_or_address)
    except ValueError as err:
        raise ConfigError(
            f"scheduler {cluster_or_address!r} is not a Dask scheduler address ({err}); "
            "give one as tcp://HOST:PORT"
        ) from None
    try:
        return Client(cluster_or_address, timeout=10)
    except OSError as err:
        raise RigError(f"no Dask scheduler answers at {cluster_or_address!r}: {err}") from None
