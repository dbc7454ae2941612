"""`rig sim`: the simulated rig — serve its device peers, or render a scene."""

from __future__ import annotations

import signal
import threading
import tomllib
from enum import Enum
from pathlib import Path
from typing import Annotated, Literal

import typer
from rich.markup import escape
from typer.core import TyperGroup

from orchestrator.cli.common import console
from rig.config import RIG_KINDS
from rig.errors import ConfigError

__all__ = ["app", "parse_faults"]


# what --config-kind accepts: the rig kinds
Kind = Enum("Kind", {kind: kind for kind in RIG_KINDS}, type=str)


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


def parse_faults(specs: list[str]) -> dict[str, dict]:
    """``["cameras.dropped_frames=2", "lamp_bank.dead_lamps=['L3']"]`` → fault tables.

    Values are TOML values (numbers, booleans, quoted strings, arrays).
    """
    faults: dict[str, dict] = {}
    for spec in specs:
        key, sep, value = spec.partition("=")
        peer, dot, name = key.strip().partition(".")
        if not (sep and dot and peer and name):
            raise ConfigError(
                f"--fault {spec!r}: expected PEER.KEY=VALUE, e.g. cameras.dropped_frames=1"
            )
        try:
            parsed = tomllib.loads(f"v = {value.strip()}")["v"]
        except tomllib.TOMLDecodeError as err:
            raise ConfigError(f"--fault {spec!r}: {value!r} is not a TOML value ({err})") from None
        faults.setdefault(peer, {})[name] = parsed
    return faults


@app.command()
def serve(
    scene: Annotated[Path, typer.Argument(help="scene TOML")],
    config_out: Annotated[
        Path, typer.Option("--config-out", help="where to write the rig config for the daemon")
    ] = Path("sim-rig.toml"),
    speed: Annotated[
        float, typer.Option(min=0.001, help="simulated time runs this many times faster")
    ] = 1.0,
    transport: Annotated[
        str, typer.Option(help="Modbus transport: tcp (loopback) or rtu (on ptys)")
    ] = "tcp",
    fault: Annotated[
        list[str] | None,
        typer.Option(
            "--fault",
            help="inject a fault, PEER.KEY=VALUE (peers: turntable, lamp_bank, light_arc, "
            "laser, cameras), e.g. cameras.dropped_frames=1; repeatable",
        ),
    ] = None,
    config_kind: Annotated[
        Kind | None,
        typer.Option(
            "--config-kind",
            help="simulate this kind of rig (its default geometry unless the scene gives it); "
            "default: the scene's",
        ),
    ] = None,
) -> None:
    """Start all device peers and the camera server; write the rig config that reaches them.

    Then, in another shell: `rig daemon --config sim-rig.toml` and `rig submit PLAN`.
    Ctrl-C stops the simulated rig.
    """
    from rig.clock import RealClock, ScaledClock
    from rig.config import write_rig_config
    from sim.rig import SimulatedRig
    from sim.scene import load_scene

    if transport not in ("tcp", "rtu"):
        raise ConfigError(f"--transport {transport!r}: valid are 'tcp' and 'rtu'")
    mode: Literal["tcp", "rtu"] = "tcp" if transport == "tcp" else "rtu"
    clock = RealClock() if speed == 1.0 else ScaledClock(speed)
    stop = threading.Event()
    handlers = {
        sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGINT, signal.SIGTERM)
    }
    try:
        the_scene = load_scene(scene, kind=config_kind.value if config_kind else None)
        with SimulatedRig(
            the_scene, clock=clock, transport=mode, faults=parse_faults(fault or [])
        ) as sim:
            path = write_rig_config(sim.rig_config(), config_out)
            console.print(
                escape(
                    f"simulated rig {sim.scene.rig.name!r} of scene {scene} is up "
                    f"(time ×{speed:g}); rig config written to {path}"
                )
            )
            console.print(escape(f"next: rig daemon --config {path}   (Ctrl-C here stops the rig)"))
            stop.wait()
    finally:
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
    console.print("simulated rig stopped")


@app.command()
def render(
    scene: Annotated[Path, typer.Argument(help="scene TOML")],
    out: Annotated[Path, typer.Option("--out", help="folder for the PNGs")] = Path("out/sim"),
    cameras: Annotated[int, typer.Option(min=1, help="how many cameras, spread over the arc")] = 3,
    lamps: Annotated[int, typer.Option(min=1, help="how many lamps, spread over the arc")] = 2,
) -> None:
    """Render a scene from the rig's cameras and write PNGs a person can look at.

    Writes one image per camera × lamp, a laser frame, and the true normals,
    height and albedo maps.
    """
    from sim.preview import write_preview

    written = write_preview(scene, out, cameras=cameras, lamps=lamps)
    for path in written:
        console.print(escape(f"wrote {path}"))
