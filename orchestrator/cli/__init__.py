"""The `rig` command line: one entry point for every job of the rig.

Exit codes: 0 success, 1 a device or runtime failure, 2 invalid input (plan,
config, arguments), 3 a command that is not built yet.
"""

from __future__ import annotations

import logging

import typer

from orchestrator.cli import (
    bench_cmd,
    calibrate_cmd,
    pending,
    plan_cmd,
    process_cmd,
    repair_cmd,
    session_cmd,
    sim_cmd,
)
from orchestrator.cli.common import console

__all__ = ["app", "main"]

app = typer.Typer(
    name="rig",
    help="btfrig: measure BTF, MDF and photometric stereo of material samples.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
plan_cmd.register(app)
session_cmd.register(app)
process_cmd.register(app)
repair_cmd.register(app)
calibrate_cmd.register(app)
pending.register(app)
app.add_typer(sim_cmd.app, name="sim")
app.add_typer(bench_cmd.app, name="bench")


def main() -> None:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        app()
    except KeyboardInterrupt:
        console.print("[yellow]interrupted[/yellow]")
        raise SystemExit(130) from None
