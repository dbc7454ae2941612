"""Local session commands: a daemon, workers and a client in this one process."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from orchestrator.cli.common import SessionProgress, check_new_archive
from orchestrator.cli.session_cmd import FaultHints, print_status
from rig.errors import ConfigError

__all__ = ["register"]


def run(
    plan: Annotated[Path, typer.Argument(help="plan TOML")],
    config: Annotated[
        Path | None, typer.Option("--config", "-c", help="rig config TOML (default rig)")
    ] = None,
    archive: Annotated[
        Path | None, typer.Option("--archive", help="where to write (default: the plan's)")
    ] = None,
    workers: Annotated[
        int, typer.Option(min=1, help="live workers to run (frames wait for one)")
    ] = 1,
    stages: Annotated[
        str,
        typer.Option("--stages", help="the workers' live stages: stats, register, laser, ps"),
    ] = "stats",
    sim: Annotated[
        Path | None,
        typer.Option(
            "--sim",
            help="run against the simulated rig of this scene TOML, in virtual time "
            "(instead of --config's hardware)",
        ),
    ] = None,
) -> None:
    """Run a local session: daemon, workers and client in one process.

    The client submits PLAN and follows the session to its end, as `rig submit`
    and `rig status --follow` would; the exit status is 1 when it does not end done.
    """
    from orchestrator.local import run_local
    from orchestrator.worker import worker_stages
    from rig.plan import load_plan

    if config is not None and sim is not None:
        raise ConfigError("--config and --sim: give one (the scene names its rig)")
    try:
        worker_stages(stages)
    except ConfigError as err:
        raise ConfigError(f"--stages: {err}") from None
    # The daemon runs here: its archive's folder must be one this machine can make.
    option = "--archive" if archive is not None else "the plan's output.archive"
    archive = archive if archive is not None else load_plan(plan).archive_path()
    check_new_archive(archive, option, otherwise="`rig resume` an unfinished one")
    with SessionProgress() as progress:
        view = FaultHints(progress)
        if sim is None:
            final = run_local(
                plan, config, archive=archive, workers=workers, stages=stages, on_event=view
            )
        else:
            from rig.clock import VirtualClock
            from sim.rig import SimulatedRig

            clock = VirtualClock()
            with SimulatedRig(sim, clock=clock) as rig:
                final = run_local(
                    plan, rig.rig_config(), archive=archive, workers=workers,
                    stages=stages, on_event=view, clock=clock,
                )  # fmt: skip
    print_status(final)
    if final.get("state") != "done":
        raise typer.Exit(1)


def replay(
    archive: Annotated[Path, typer.Argument(help="session archive to replay")],
    out: Annotated[
        Path | None,
        typer.Option("--out", help="the replay's archive (default: ARCHIVE.replay.zarr)"),
    ] = None,
    speed: Annotated[
        float, typer.Option("--speed", min=0.001, help="pace: N times the recorded speed")
    ] = 1.0,
    max_speed: Annotated[
        bool, typer.Option("--max", help="as fast as the archive reads (ignores --speed)")
    ] = False,
    workers: Annotated[int, typer.Option(min=1, help="statistics workers to run")] = 1,
) -> None:
    """Run a recorded session back through the daemon and workers.

    The plan, rig config and frames come from ARCHIVE; moves, lamps, cameras and
    exposures are checked against the recording, and a mismatch fails the replay.
    """
    from orchestrator.local import replay_local

    target = out if out is not None else archive.with_suffix(".replay.zarr")
    check_new_archive(target, "--out", otherwise="remove that replay first")
    with SessionProgress() as view:
        final = replay_local(
            archive, out=target, speed=None if max_speed else speed, workers=workers,
            on_event=view,
        )  # fmt: skip
    print_status(final)
    if final.get("state") != "done":
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add `rig run` and `rig replay` to ``app``."""
    for command in (run, replay):
        app.command()(command)
