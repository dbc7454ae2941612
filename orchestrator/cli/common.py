"""What every `rig` command shares: the console, exit codes, error reporting."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from rig.config import RigConfig, default_rig_config, load_rig_config
from rig.errors import ConfigError, PlanError, RigError

__all__ = [
    "EXIT_FAILURE",
    "EXIT_INVALID",
    "EXIT_NOT_BUILT",
    "OPTIONAL_EXTRAS",
    "SessionProgress",
    "console",
    "load_config_option",
    "not_built",
    "reporting_errors",
]

# Wide when piped (logs, CI), so benchmark tables do not wrap at 80 columns.
console = Console(highlight=False, width=None if sys.stdout.isatty() else 160)
err_console = Console(stderr=True, highlight=False, width=None if sys.stderr.isatty() else 160)

EXIT_FAILURE = 1
EXIT_INVALID = 2
EXIT_NOT_BUILT = 3

# The optional packages a command may need, by top-level module, and the extra that installs them.
OPTIONAL_EXTRAS = {
    "distributed": "dask",
    "dask": "dask",
    "pyrender": "sim",
    "trimesh": "sim",
    "embreex": "sim",
    "rtree": "sim",
    "moderngl": "render",
    "mitsuba": "reference",
    "harvesters": "genicam",
    "genicam": "genicam",
}


@contextmanager
def reporting_errors() -> Iterator[None]:
    """Turn domain errors into a readable message and the right exit code.

    A missing optional package is a failure (exit 1) that names the extra to install.
    """
    try:
        yield
    except ModuleNotFoundError as err:
        extra = OPTIONAL_EXTRAS.get((err.name or "").split(".")[0])
        if extra is None:
            raise
        advice = f"install btfrig[{extra}] (pip install 'btfrig[{extra}]')"
        err_console.print(
            f"[red]error:[/red] this command needs the optional package {err.name!r}: "
            + escape(advice)
        )
        raise typer.Exit(EXIT_FAILURE) from err
    except (PlanError, ConfigError) as err:
        err_console.print(f"[red]error:[/red] {err}")
        raise typer.Exit(EXIT_INVALID) from err
    except RigError as err:
        err_console.print(f"[red]error:[/red] {err}")
        raise typer.Exit(EXIT_FAILURE) from err


def load_config_option(path: Path | None) -> RigConfig:
    """The rig config at ``path``, or the default rig when none is given."""
    return default_rig_config() if path is None else load_rig_config(path)


def not_built(command: str, issue: int | None, what: str) -> None:
    """Say plainly that a command does not exist yet, and fail."""
    tracked = f"tracked in issue {issue}" if issue is not None else "not scheduled yet"
    err_console.print(
        f"[yellow]rig {command}:[/yellow] not built yet — {what} ({tracked}). Nothing was done."
    )
    raise typer.Exit(EXIT_NOT_BUILT)


def _hms(seconds) -> str:
    if seconds is None:
        return "?"
    s = round(seconds)
    return f"{s // 3600:d}:{s % 3600 // 60:02d}:{s % 60:02d}"


class SessionProgress:
    """Draws a session's events: a bar for progress, lines for the rest."""

    def __init__(self) -> None:
        self.progress = Progress(
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            TextColumn("step {task.completed:.0f}/{task.total:.0f}"),
            TextColumn("ETA {task.fields[eta]}"),
            TextColumn("{task.fields[fps]} frames/s"),
            TimeElapsedColumn(),
            console=console,
        )
        self.task = None

    def __enter__(self) -> SessionProgress:
        self.progress.start()
        return self

    def __exit__(self, *exc) -> None:
        self.progress.stop()

    def __call__(self, event: dict) -> None:
        topic = event.get("topic")
        if topic == "progress":
            fields = {
                "eta": _hms(event.get("eta_s")),
                "fps": f"{event.get('frames_per_s', 0.0):.1f}",
            }
            if self.task is None:
                self.task = self.progress.add_task("session", total=event["steps"], **fields)
            self.progress.update(self.task, completed=event["step"], **fields)
        elif topic == "state":
            self.progress.console.print(f"state: {event.get('from')} → [bold]{event.get('to')}[/]")
        elif topic == "log":
            detail = {k: v for k, v in event.items() if k not in ("topic", "seq", "time", "kind")}
            self.progress.console.print(f"{event.get('kind')}: {detail}")
        elif topic == "gap":
            self.progress.console.print(f"[yellow]missed {event['missed']} event(s)[/yellow]")
