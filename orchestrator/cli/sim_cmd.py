"""`rig sim`: the simulated rig — serve its device peers, or render a scene."""

from __future__ import annotations

import signal
import threading
import tomllib
from enum import Enum
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import typer
from rich.markup import escape
from typer.core import TyperGroup

from orchestrator.cli.common import PLAIN_HELP, console, prepare_file
from rig.errors import ConfigError
from rig.kinds import kind_names

__all__ = ["app", "parse_faults"]


# what --config-kind accepts: the rig kinds
Kind = Enum("Kind", {kind: kind for kind in kind_names()}, type=str)


class _DefaultServe(TyperGroup):
    """`rig sim SCENE` means `rig sim serve SCENE`."""

    def parse_args(self, ctx, args):
        if args and args[0] not in self.commands and not args[0].startswith("-"):
            args = ["serve", *args]
        return super().parse_args(ctx, args)


app = typer.Typer(
    cls=_DefaultServe,
    no_args_is_help=True,
    rich_markup_mode=PLAIN_HELP,
    short_help="The simulated rig: serve its devices, draw or ray-cast a scene.",
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
            metavar="<str>",
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
    """Serve the simulated rig: its device peers and camera server.

    Writes the rig config that reaches them (--config-out). Then, in another
    shell: `rig daemon --config sim-rig.toml` and `rig submit PLAN`. Ctrl-C stops
    the simulated rig.
    """
    from rig.clock import RealClock, ScaledClock
    from rig.config import write_rig_config
    from sim.rig import SimulatedRig
    from sim.scene import load_scene

    if transport not in ("tcp", "rtu"):
        raise ConfigError(f"--transport {transport!r}: valid are 'tcp' and 'rtu'")
    prepare_file(config_out, "--config-out")  # before the peers start
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
    """Render a scene from the rig's cameras into PNGs to look at.

    Writes one image per camera × lamp, a laser frame, and the true normals,
    height and albedo maps.
    """
    from sim.preview import write_preview

    written = write_preview(scene, out, cameras=cameras, lamps=lamps)
    for path in written:
        console.print(escape(f"wrote {path}"))


def _angles(text: str, option: str, count: int | None = None) -> tuple[float, ...]:
    """``"45,20"`` → (45.0, 20.0); ``ConfigError`` naming the option otherwise."""
    try:
        values = tuple(float(part) for part in text.split(","))
    except ValueError:
        values = ()
    if not values or (count is not None and len(values) != count):
        want = f"{count} numbers" if count else "numbers"
        raise ConfigError(f"{option} {text!r}: expected {want} separated by commas, e.g. 45,20")
    return values


@app.command()
def coverage(
    scene: Annotated[Path, typer.Argument(help="scene TOML")],
    mounts: Annotated[
        list[str] | None,
        typer.Option(
            metavar="<str>",
            help="laser mount angles θ, e.g. 45,20 (repeat for several rigs; "
            "default: the scene's rig)"
        ),
    ] = None,
    view: Annotated[str, typer.Option(help="view direction θ,φ in degrees")] = "0,0",
    goal: Annotated[float, typer.Option(min=0.01, max=1.0, help="coverage to reach")] = 0.99,
    size: Annotated[int, typer.Option(min=8, max=1024, help="texels per side")] = 128,
    even: Annotated[str, typer.Option(help="location counts evenly in azimuth (one mount)")] = (
        "1,5,13,26"
    ),
    start: Annotated[int, typer.Option(min=1, help="even locations the choice completes")] = 5,
) -> None:
    """Which texels MDF laser scans reach, per locations and mounts.

    Prints a markdown table of the coverage against laser locations and mounts,
    beside the capture time, and, for several mounts, the chosen locations for a
    plan's `laser_locations`.

    Ray casts the scene's sample (no rendering): a texel counts when the camera
    sees it and a sheet the rig can produce reaches it without grazing the view.
    """
    from sim.coverage import coverage_rows
    from sim.model import SceneModel
    from sim.scene import load_scene

    loaded = load_scene(scene)
    mount_sets = [_angles(m, "--mounts") for m in mounts or []] or [
        loaded.rig.laser.mount_theta_deg
    ]
    counts = tuple(int(c) for c in _angles(even, "--even"))
    if any(c < 1 for c in counts):
        raise ConfigError(f"--even {even!r}: counts must be ≥ 1")
    rows = coverage_rows(
        SceneModel(loaded), loaded.rig, _angles(view, "--view", 2), mounts=mount_sets,
        even=counts, start=start, goal=goal, n=size,
    )  # fmt: skip
    console.print("| mounts θ (°) | locations | chosen | coverage | capture (s) |", soft_wrap=True)
    console.print("|---|---|---|---|---|")
    for row in rows:
        mounts_text = ", ".join(f"{m:g}" for m in row["mounts"])
        console.print(
            f"| {mounts_text} | {len(row['locations'])} | {row['choice']} | "
            f"{row['coverage']:.3f} | {row['capture_s']:.0f} |",
            soft_wrap=True,
        )
    for row in rows:
        if "greedy" in row["choice"]:
            where = ", ".join(f"[{t:g}, {p:g}]" for t, p in np.round(row["locations"], 2))
            heading = f"# mounts {list(row['mounts'])}, {row['choice']}:"
            console.print(
                escape(f"{heading}\nlaser_locations = [{where}]"),
                soft_wrap=True,
            )
