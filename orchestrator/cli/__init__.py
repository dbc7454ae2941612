"""The `rig` command line: one entry point for every job of the rig.

Exit codes: 0 success, 1 a device or runtime failure, 2 invalid input (plan,
config, arguments, files to import). Every error is one
message naming what failed; ``rig --debug …`` also prints the traceback.
"""

from __future__ import annotations

import logging
from typing import Annotated

import typer

from orchestrator.cli import (
    bench_cmd,
    calibrate_cmd,
    export_cmd,
    import_cmd,
    local_cmd,
    plan_cmd,
    process_cmd,
    repair_cmd,
    session_cmd,
    sim_cmd,
    view_cmd,
)
from orchestrator.cli.common import PLAIN_HELP, RigGroup, console

__all__ = ["app", "main"]

app = typer.Typer(
    name="rig",
    help="btfrig: measure BTF, MDF and photometric stereo of material samples.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    cls=RigGroup,
    rich_markup_mode=PLAIN_HELP,
)


@app.callback()
def _options(
    debug: Annotated[
        bool, typer.Option("--debug", help="on an error, also print the traceback")
    ] = False,
) -> None:
    """Options of every command (``RigGroup`` reads --debug from the context)."""


plan_cmd.register(app)
session_cmd.register(app)
local_cmd.register(app)
process_cmd.register(app)
repair_cmd.register(app)
calibrate_cmd.register(app)
view_cmd.register(app)
import_cmd.register(app)
app.add_typer(sim_cmd.app, name="sim")
app.add_typer(bench_cmd.app, name="bench")
app.add_typer(export_cmd.app, name="export")


def main() -> None:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        app()
    except KeyboardInterrupt:
        console.print("[yellow]interrupted[/yellow]")
        raise SystemExit(130) from None
