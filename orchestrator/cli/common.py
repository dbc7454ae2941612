"""What every `rig` command shares: the console, exit codes, error reporting."""

from __future__ import annotations

import logging
import signal
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    SpinnerColumn,
    TextColumn,
    TimeElapsedColumn,
)
from typer.core import TyperGroup

from rig.config import RigConfig, default_rig_config, load_rig_config
from rig.errors import ConfigError, KinematicsError, PlanError, RigError

__all__ = [
    "EXIT_FAILURE",
    "EXIT_INVALID",
    "EXTRAS",
    "PLAIN_HELP",
    "RigGroup",
    "SessionProgress",
    "check_new_archive",
    "console",
    "flagged_lines",
    "load_config_option",
    "prepare_file",
    "prepare_folder",
    "quiet_dask_logs",
    "readable",
    "reporting_errors",
    "terminating_as_interrupt",
    "working",
]

# Wide when piped (logs, CI), so benchmark tables do not wrap at 80 columns. Lines of
# text are never wrapped or cropped (soft_wrap): a path or a message stays whole on
# one line at any width, and the terminal folds what is longer.
console = Console(highlight=False, soft_wrap=True, width=None if sys.stdout.isatty() else 160)
err_console = Console(
    stderr=True, highlight=False, soft_wrap=True, width=None if sys.stderr.isatty() else 160
)

#: ``rich_markup_mode`` of every `rig` command group: click's plain help, whose lines
#: wrap between words at any width, and usage errors as one line (rich's panels cut
#: option syntax at 80 columns and wrap an error's words across box lines).
PLAIN_HELP = None

EXIT_FAILURE = 1
EXIT_INVALID = 2


#: import name of an optional package → the extra of btfrig that installs it
EXTRAS = {
    "dask": "dask",
    "distributed": "dask",
    "pyrender": "sim",
    "OpenGL": "sim",
    "trimesh": "sim",
    "rtree": "sim",
    "embreex": "sim",
    "moderngl": "render",
    "OpenEXR": "render",
    "PIL": "render",
    "mitsuba": "reference",
    "harvesters": "genicam",
    "genicam": "genicam",
}


def _report(err: Exception) -> tuple[str, int]:
    """The message and exit code of an error that ends a command."""
    if isinstance(err, PlanError | ConfigError | KinematicsError):  # what was asked is wrong
        return str(err), EXIT_INVALID
    if isinstance(err, RigError):
        return str(err), EXIT_FAILURE
    if isinstance(err, ModuleNotFoundError) and err.name is not None:
        package = err.name.split(".")[0]
        if package in EXTRAS:
            return (
                f"the optional package {package!r} is not installed; "
                f"install it with: pip install 'btfrig[{EXTRAS[package]}]'",
                EXIT_FAILURE,
            )
    if isinstance(err, OSError):
        return str(err), EXIT_FAILURE  # names the path: "[Errno 20] Not a directory: '…'"
    return (
        f"unexpected {type(err).__name__}: {err} (`rig --debug …` shows where it happened)",
        EXIT_FAILURE,
    )


@contextmanager
def reporting_errors(*, debug: bool = False) -> Iterator[None]:
    """The one place a command's error is printed: one message and an exit code
    (2 invalid input, 1 failure), never a traceback unless ``debug``.

    Typer's own exits and usage errors pass through (typer prints those).
    """
    try:
        yield
    except (typer.Exit, typer.Abort, typer.TyperException):
        raise
    except Exception as err:
        message, code = _report(err)
        if debug:
            err_console.print_exception()
        # rich markup would eat bracketed text of the message ("[…]", "[dask]")
        err_console.print(f"[red]error:[/red] {escape(message)}")
        raise typer.Exit(code) from err


@contextmanager
def terminating_as_interrupt() -> Iterator[None]:
    """SIGTERM handled like Ctrl-C (SIGINT) while the block runs: a KeyboardInterrupt,
    so a command's clean-up (a half-written output removed) runs on either."""

    def interrupt(signum, frame):
        raise KeyboardInterrupt(f"signal {signal.Signals(signum).name}")

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class RigGroup(TyperGroup):
    """The `rig` command group: every command's errors go through ``reporting_errors``."""

    def invoke(self, ctx: typer.Context):
        with reporting_errors(debug=bool(ctx.params.get("debug"))):
            return super().invoke(ctx)


def load_config_option(path: Path | None) -> RigConfig:
    """The rig config at ``path``, or the default rig when none is given."""
    return default_rig_config() if path is None else load_rig_config(path)


def quiet_dask_logs() -> None:
    """Dask's loggers to WARNING: their INFO lines are for its developers. A worker's
    "Compute Failed" report (the task's traceback) is dropped: the command reports the
    task's error itself, once, with the traceback under ``--debug``."""
    import distributed  # noqa: F401  (configures its loggers on import)

    for name in list(logging.root.manager.loggerDict):
        if name.split(".")[0] == "distributed":
            logging.getLogger(name).setLevel(logging.WARNING)
    worker = logging.getLogger("distributed.worker")
    if not any(isinstance(f, _TaskFailures) for f in worker.filters):
        worker.addFilter(_TaskFailures())


class _TaskFailures(logging.Filter):
    """Drops a Dask worker's "Compute Failed" records."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not str(record.msg).startswith("Compute Failed")


def prepare_folder(path: Path, option: str) -> Path:
    """Create the folder ``path`` (for ``option``, e.g. ``"--previews DIR"``); a
    ``ConfigError`` naming both and why when it cannot be made."""
    _refuse_file_on_the_way(path, option)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ConfigError(
            f"{option}: cannot create the folder {path} ({err.strerror}); give a writable one"
        ) from None
    return path


def prepare_file(path: Path, option: str) -> Path:
    """Create the folder of the file ``path`` (for ``option``, e.g. ``"--out"``) before
    any work is done; a ``ConfigError`` naming both when ``path`` is a folder or its
    folder cannot be made (a file on the way, no permission)."""
    if path.is_dir():
        raise ConfigError(f"{option} {path}: is a folder; give a file's path")
    prepare_folder(path.parent, f"{option} {path}")
    return path


def check_new_archive(path: Path, option: str, *, otherwise: str) -> None:
    """Refuse an archive path (given as ``option``) that exists or lies under a file,
    before a daemon starts; ``otherwise`` says what to do with an existing one."""
    if path.exists():
        raise ConfigError(f"{option} {path} exists; give a new path, or {otherwise}")
    _refuse_file_on_the_way(path.parent, f"{option} {path}")


def _refuse_file_on_the_way(folder: Path, option: str) -> None:
    blocking = next((p for p in (folder, *folder.parents) if p.exists() and not p.is_dir()), None)
    if blocking is not None:
        raise ConfigError(f"{option}: {blocking} is a file, not a folder; give another path")


@contextmanager
def working(what: str, *, total: int | None = None) -> Iterator[Callable[[], None]]:
    """Say on stderr that a long wait is ``what`` (e.g. "compiling 6561 steps"): on a
    terminal a spinner, or a bar of ``total`` steps, with the elapsed time, gone when
    done; to a pipe or a log one line. Yields ``advance()``, to call once per step."""
    if not err_console.is_terminal:
        err_console.print(escape(f"{what} …"))
        yield lambda: None
        return
    counted = [BarColumn(), MofNCompleteColumn()] if total is not None else []
    columns = (SpinnerColumn(), TextColumn("{task.description}"), *counted, TimeElapsedColumn())
    with Progress(*columns, console=err_console, transient=True) as progress:
        task = progress.add_task(escape(what), total=total)
        yield lambda: progress.advance(task)


def readable(value) -> str:
    """A daemon's reply or event field as words, not Python's repr: a mapping as
    ``key value, key value`` (nested ones in parentheses), a list comma-separated."""
    if isinstance(value, dict):
        return ", ".join(
            f"{key.replace('_', ' ')} {_nested(item)}"
            for key, item in value.items()
            if item is not None
        )
    if isinstance(value, list | tuple):
        return ", ".join(_nested(item) for item in value)
    return str(value)


def _nested(value) -> str:
    text = readable(value)
    return f"({text})" if isinstance(value, dict | list | tuple) else text


def flagged_lines(summary: dict) -> list[str]:
    """``rig.frame_check.flag_summary`` as lines for a user: how many frames did not
    record their step's state, at which steps, what became of them, and why."""
    if not summary.get("frames"):
        return []
    steps = ", ".join(str(s) for s in summary["steps"])
    lines = [
        f"flagged: {summary['frames']} frame(s) did not record their step's state "
        f"(steps {steps}): {summary['recaptured']} taken again and matched, "
        f"{summary['left_out']} still mismatched (processing leaves them out)"
    ]
    lines += [f"  step {step}: {why}" for step, why in summary["reasons"].items()]
    if len(summary["steps"]) > len(summary["reasons"]):
        lines.append(f"  … and {len(summary['steps']) - len(summary['reasons'])} more step(s)")
    return lines


def _hms(seconds) -> str:
    if seconds is None:
        return "?"
    s = round(seconds)
    return f"{s // 3600:d}:{s % 3600 // 60:02d}:{s % 60:02d}"


class SessionProgress:
    """Draws a session's events: a bar for progress, lines for the rest.

    Where the output is no terminal (a pipe, a log file) there is no bar, which
    would hold every line back until it stops: each event is one line, at once.
    """

    def __init__(self) -> None:
        self.lines = not console.is_terminal
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
        self.state: str | None = None

    def __enter__(self) -> SessionProgress:
        if not self.lines:
            self.progress.start()
        return self

    def __exit__(self, *exc) -> None:
        if not self.lines:
            self.progress.stop()

    def __call__(self, event: dict) -> None:
        topic = event.get("topic")
        if topic == "progress":
            fields = {
                "eta": _hms(event.get("eta_s")),
                "fps": f"{event.get('frames_per_s', 0.0):.1f}",
            }
            if self.lines:
                console.print(
                    f"step {event.get('step')}/{event.get('steps')}, ETA {fields['eta']}, "
                    f"{fields['fps']} frames/s"
                )
                return
            if self.task is None:
                self.task = self.progress.add_task("session", total=event["steps"], **fields)
            self.progress.update(self.task, completed=event["step"], **fields)
        elif topic == "state":
            self.state = event.get("to")
            self.progress.console.print(f"state: {event.get('from')} → [bold]{event.get('to')}[/]")
        elif topic == "status" and event.get("state") != self.state:  # a first look, or news
            self.state = event.get("state")
            self.progress.console.print(escape(f"daemon: {self.state}"))
        elif topic == "log":
            detail = {k: v for k, v in event.items() if k not in ("topic", "seq", "time", "kind")}
            action = detail.pop("action", None)  # "session start: …", not "session: action …"
            what = event.get("kind") if action is None else f"{event.get('kind')} {action}"
            self.progress.console.print(escape(f"{what}: {readable(detail)}"))
        elif topic == "flagged":
            self.progress.console.print(
                escape(
                    f"step {event['step']}: {event['frames']} frame(s) flagged, "
                    f"{event['recaptured']} taken again and matched ({event['reason']})"
                ),
                style="yellow",
            )
        elif topic == "gap":
            self.progress.console.print(f"[yellow]missed {event['missed']} event(s)[/yellow]")
