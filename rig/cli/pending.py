"""Commands DESIGN.md names whose implementation has not landed yet.

Each exists with its help text and fails with exit code 3, saying so: no fake
success. A command moves out of this module when it is built.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rig.cli.common import not_built

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    @app.command()
    def daemon(
        config: Annotated[Path, typer.Option("--config", "-c", help="rig config TOML")],
    ) -> None:
        """Run the control daemon: owns the devices and one session at a time."""
        not_built("daemon", 5, "the ZeroMQ control daemon")

    @app.command()
    def submit(plan: Annotated[Path, typer.Argument(help="plan TOML")]) -> None:
        """Submit a plan to the running daemon."""
        not_built("submit", 5, "the daemon client")

    @app.command()
    def status(
        follow: Annotated[bool, typer.Option("--follow", "-f", help="keep following")] = False,
    ) -> None:
        """Show the daemon's session state and progress."""
        not_built("status", 5, "the daemon client")

    @app.command()
    def pause() -> None:
        """Pause the running session after the current step."""
        not_built("pause", 5, "the daemon client")

    @app.command()
    def resume(
        archive: Annotated[
            Path | None, typer.Argument(help="resume a crashed session from its archive")
        ] = None,
    ) -> None:
        """Resume a paused session, or continue a crashed one from its archive."""
        not_built("resume", 5, "session resume")

    @app.command()
    def abort() -> None:
        """Abort the running session (committed steps stay in the archive)."""
        not_built("abort", 5, "the daemon client")

    @app.command()
    def shutdown() -> None:
        """Stop the daemon cleanly."""
        not_built("shutdown", 5, "the daemon client")

    @app.command()
    def run(
        plan: Annotated[Path, typer.Argument(help="plan TOML")],
        config: Annotated[Path, typer.Option("--config", "-c", help="rig config TOML")],
    ) -> None:
        """Daemon + submit + follow in one process, for a local session."""
        not_built("run", 5, "the local session runner")

    @app.command()
    def worker(
        stage: Annotated[str, typer.Argument(help="processing stage to run")],
        connect: Annotated[str, typer.Option("--connect", help="tcp://HOST")] = "tcp://127.0.0.1",
    ) -> None:
        """Pull frames from a daemon, run a processing stage, push results."""
        not_built("worker", 5, "processing workers")

    @app.command()
    def replay(
        archive: Annotated[Path, typer.Argument(help="session archive")],
        speed: Annotated[float, typer.Option("--speed", help="replay speed factor")] = 1.0,
        max_speed: Annotated[bool, typer.Option("--max", help="as fast as possible")] = False,
    ) -> None:
        """Run a recorded session back through the daemon and workers."""
        not_built("replay", 5, "session replay")

    @app.command()
    def process(
        archive: Annotated[Path, typer.Argument(help="session archive")],
        stages: Annotated[str, typer.Option("--stages", help="e.g. ps,btf,mdf")] = "ps,btf,mdf",
        scheduler: Annotated[
            str | None, typer.Option("--scheduler", help="Dask scheduler address")
        ] = None,
    ) -> None:
        """Run processing stages over a recorded archive into its material/ group."""
        not_built("process", 6, "offline processing on Dask")

    @app.command()
    def calibrate(
        target: Annotated[str, typer.Argument(help="cameras | lamps | laser | response")],
        config: Annotated[Path, typer.Option("--config", "-c", help="rig config TOML")],
    ) -> None:
        """Calibrate cameras, lamps, laser planes or the radiometric response."""
        not_built("calibrate", 9, "calibration sessions")

    @app.command()
    def view(
        material: Annotated[Path, typer.Argument(help="archive with a material/ group")],
        out: Annotated[Path | None, typer.Option("--out", help="write a PNG")] = None,
    ) -> None:
        """Render a material on a mesh (headless PNG or a window)."""
        not_built("view", None, "the GL renderer")

    @app.command("export")
    def export_(
        archive: Annotated[Path, typer.Argument(help="session archive")],
        fmt: Annotated[str, typer.Option("--format", help="png16 | tiff | exr | ubo2003")],
        out: Annotated[Path, typer.Option("--out", help="output folder")],
    ) -> None:
        """Write frames or the material in common formats."""
        not_built("export", None, "exporters")

    @app.command("import")
    def import_(
        folder: Annotated[Path, typer.Argument(help="a Bonn UBO2003 folder")],
        out: Annotated[Path, typer.Option("--out", help="archive to create")],
    ) -> None:
        """Read a BTF in the Bonn UBO2003 layout into an archive."""
        not_built("import", None, "the UBO2003 importer")
