"""`rig sim`: the simulated rig — serve its device peers, or render a scene."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from typer.core import TyperGroup

from rig.cli.common import not_built

__all__ = ["app"]


class _DefaultServe(TyperGroup):
    """`rig sim SCENE` means `rig sim serve SCENE`."""

    def parse_args(self, ctx, args):
        if args and args[0] not in self.commands and not args[0].startswith("-"):
            args = ["serve", *args]
        return super().parse_args(ctx, args)


app = typer.Typer(
    cls=_DefaultServe,
    no_args_is_help=True,
    help="The simulated rig: `rig sim SCENE` serves its devices; `rig sim render` draws it.",
)


@app.command()
def serve(
    scene: Annotated[Path, typer.Argument(help="scene TOML")],
    config_out: Annotated[
        Path, typer.Option("--config-out", help="where to write the rig config for the daemon")
    ] = Path("sim-rig.toml"),
) -> None:
    """Start all device peers and the camera server; print the rig config that reaches them."""
    not_built("sim", 4, "the simulated device peers")


@app.command()
def render(
    scene: Annotated[Path, typer.Argument(help="scene TOML")],
    out: Annotated[Path, typer.Option("--out", help="folder for the PNGs")] = Path("out/sim"),
) -> None:
    """Render a scene from the rig's cameras and write PNGs a person can look at."""
    not_built("sim render", 3, "the simulator's image formation")
