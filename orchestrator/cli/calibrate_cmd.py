"""`rig calibrate`: capture a calibration session, compute, write the calibration file."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from orchestrator.cli.common import (
    EXIT_FAILURE,
    SessionProgress,
    check_new_archive,
    console,
    load_config_option,
    prepare_folder,
    readable,
)
from rig.errors import ConfigError, RigError

__all__ = ["CaptureOptions", "register"]

_TARGETS = ("cameras", "lamps", "laser", "response")


@dataclass(frozen=True)
class CaptureOptions:
    """How `rig calibrate` captures its sessions: ``poses`` turntable angles (cameras),
    the ``cameras`` ids to use (None: the target's default), and with ``sim`` from the
    simulated rig at ``scale`` times the cameras' image size."""

    poses: int
    cameras: tuple[str, ...] | None
    sim: bool
    scale: float


def calibrate(
    target: Annotated[str, typer.Argument(help="cameras | lamps | laser | response")],
    config: Annotated[
        Path | None, typer.Option("--config", "-c", help="rig config TOML (default rig)")
    ] = None,
    sim: Annotated[
        bool, typer.Option("--sim", help="capture from the simulated rig (virtual time)")
    ] = False,
    from_archive: Annotated[
        Path | None,
        typer.Option("--from", help="compute from this recorded session instead of capturing"),
    ] = None,
    archive: Annotated[
        Path | None,
        typer.Option(
            "--archive",
            help="where the calibration session is recorded (default calibrations/TARGET.zarr)",
        ),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="calibration file to update (default: the config's, "
            "else calibrations/calibration.toml)",
        ),
    ] = None,
    poses: Annotated[int, typer.Option(min=3, help="cameras: turntable angles")] = 12,
    cameras: Annotated[
        str | None,
        typer.Option(
            "--cameras",
            help="comma-separated camera ids: cameras, lamps use them (default all); "
            "laser, response the first (default the one nearest the zenith)",
        ),
    ] = None,
    scale: Annotated[float, typer.Option(min=0.05, max=1.0, help="--sim: image size factor")] = 0.5,
    apply: Annotated[
        list[Path] | None,
        typer.Option(
            "--apply",
            metavar="<path>",
            help="also store the calibration in this session archive; repeatable",
        ),
    ] = None,
) -> None:
    """Calibrate cameras, lamps, laser planes or the camera response.

    TARGET is the cameras' geometry, the lamps' directions and intensities, the
    laser planes, or each camera's radiometric response curve. Captures a
    calibration session with the rig (or, with --sim, the simulated
    rig), computes from the archive, and updates the calibration file (its
    TARGET section, with date, software and residuals), a report and plots.
    --from ARCHIVE recomputes from a recorded (or replayed) session.
    """
    if target not in _TARGETS:
        raise ConfigError(f"unknown target {target!r}; valid are {', '.join(_TARGETS)}")
    rig = load_config_option(config)
    ids = None if cameras is None else tuple(c.strip() for c in cameras.split(",") if c.strip())
    capture = CaptureOptions(poses=poses, cameras=ids, sim=sim, scale=scale)
    if from_archive is None:
        source = archive or Path(f"calibrations/{target}.zarr")
        _capture(target, rig, source, capture)
        if target == "lamps":  # the white target: a second session
            _capture("white", rig, _white_archive(source), capture)
    else:
        source = from_archive
    failed = _compute(target, source, rig, out, apply or [])
    if failed:
        raise typer.Exit(EXIT_FAILURE)


def _white_archive(lamps_archive: Path) -> Path:
    """The white-target session that goes with a mirror-sphere session."""
    return lamps_archive.with_name(lamps_archive.stem + "-white.zarr")


def _plan(target: str, rig, archive: Path, capture: CaptureOptions) -> str:
    from calibration.plans import camera_plan, lamp_plan, laser_plan, response_plan, white_plan

    cameras = capture.cameras
    if target == "cameras":
        return camera_plan(rig, poses=capture.poses, cameras=cameras, archive=str(archive))
    if target == "lamps":
        return lamp_plan(rig, archive=str(archive), cameras=cameras)
    make = {"laser": laser_plan, "response": response_plan, "white": white_plan}[target]
    return make(rig, archive=str(archive), camera=cameras[0] if cameras else None)


def _capture(target: str, rig, archive: Path, capture: CaptureOptions) -> None:
    """Plan the calibration session of ``target`` (or "white") and record it into
    ``archive``; a ``RigError`` when the session does not end done."""
    from orchestrator.local import run_local

    check_new_archive(archive, "--archive", otherwise=f"compute from it with --from {archive}")
    prepare_folder(archive.parent, "--archive")  # calibrations/ on a fresh clone
    plan_path = archive.with_suffix(".plan.toml")
    plan_path.write_text(_plan(target, rig, archive, capture))
    console.print(escape(f"plan: {plan_path}"))
    if capture.sim:
        from rig.clock import VirtualClock
        from sim.calibration import target_scene
        from sim.rig import SimulatedRig

        clock = VirtualClock()
        scene = target_scene(target, rig, scale=capture.scale)
        with SimulatedRig(scene, clock=clock) as simulated, SessionProgress() as view:
            final = run_local(plan_path, simulated.rig_config(), archive=archive, on_event=view,
                              clock=clock)  # fmt: skip
    else:
        with SessionProgress() as view:
            final = run_local(plan_path, rig, archive=archive, on_event=view)
    if final.get("state") != "done":
        session = final.get("session") or {}
        why = session.get("reason") or readable(session.get("fault") or {}) or "no reason given"
        raise RigError(f"the calibration session of {archive} ended {final.get('state')}: {why}")


def _compute(target: str, source: Path, rig, out: Path | None, apply: list[Path]) -> dict:
    """Compute ``target`` from ``source``, update the calibration file; what failed."""
    from calibration.sessions import apply_calibration
    from rig.archive import software_versions
    from rig.calfile import CalibrationFile, Provenance, load_calibration, write_calibration

    path = out or Path(rig.calibration or "calibrations/calibration.toml")
    prepare_folder(path.parent, "--out")  # the plots beside it come first
    compute = {"cameras": _cameras, "laser": _laser, "response": _response, "lamps": _lamps}
    # each returns its section, what failed, and other fields of the file it sets
    section, failed, fields = compute[target](source, path)
    current = load_calibration(path) if path.exists() else CalibrationFile(rig=rig.name)
    provenance = Provenance.now(source.resolve(), software_versions())
    updated = current.with_section(target, section, provenance).model_copy(update=fields)
    write_calibration(updated, path)
    console.print(escape(f"calibration: {path} ({target})"))
    for session in apply:
        version = apply_calibration(updated, path, session)
        console.print(escape(f"{session}: calibration version {version}"))
    return failed


def _cameras(source: Path, path: Path):
    from calibration.report import camera_report, plot_camera_residuals
    from calibration.sessions import calibrate_cameras, camera_result

    found, failed = calibrate_cameras(source, progress=console.print)
    if not found:
        raise ConfigError(f"no camera could be calibrated from {source}: {failed}")
    console.print(camera_report(found, failed))
    console.print(escape(f"plot: {plot_camera_residuals(found, path.with_suffix('.cameras.png'))}"))
    return {camera_id: camera_result(cam) for camera_id, cam in found.items()}, failed, {}


def _laser(source: Path, path: Path):
    from calibration.report import laser_report
    from calibration.sessions import calibrate_laser

    results, frames = calibrate_laser(source)
    console.print(laser_report(results, frames))
    failed = {
        f"mount{m}": "no frame's strip crossed two bands"
        for m in sorted({f.mount for f in frames}) if m not in results
    }  # fmt: skip
    if not results:
        raise ConfigError(f"no laser mount could be calibrated from {source}: {failed}")
    return {f"mount{m}": r for m, r in results.items()}, failed, {}


def _response(source: Path, path: Path):
    from calibration.report import plot_response, response_report
    from calibration.sessions import calibrate_responses
    from rig.calfile import ResponseResult

    curves, exposures, failed = calibrate_responses(source)
    if not curves:
        raise ConfigError(f"no response curve could be calibrated from {source}: {failed}")
    console.print(response_report(curves, failed))
    console.print(escape(f"plot: {plot_response(curves, path.with_suffix('.response.png'))}"))
    section = {
        camera_id: ResponseResult(curve=curve.curve.tolist(), exposures=exposures)
        for camera_id, curve in curves.items()
    }
    return section, failed, {}


def _lamps(source: Path, path: Path):
    from calibration.report import lamp_report, plot_lamps
    from calibration.sessions import calibrate_lamps
    from rig.material import write_flat_field

    white = _white_archive(source)
    results, run, failed = calibrate_lamps(source, white if white.exists() else None)
    if not results:
        raise ConfigError(f"no lamp could be calibrated from {source}: {failed}")
    console.print(lamp_report(results, run, failed))
    console.print(escape(f"plot: {plot_lamps(results, path.with_suffix('.lamps.png'))}"))
    extra = {}
    if run.flat_field is not None:
        maps = write_flat_field(path.with_suffix(".flatfield.zarr"), run.flat_field)
        console.print(escape(f"flat fields: {maps} (seen by {run.flat_field.camera})"))
        extra = {"lamps_flat_field": maps.name}
    return results, failed, extra


def register(app: typer.Typer) -> None:
    """Add `rig calibrate` to ``app``."""
    app.command()(calibrate)
