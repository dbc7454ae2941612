"""Session commands: the daemon, its clients and workers."""

from __future__ import annotations

import signal
import threading
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from orchestrator.cli.common import (
    SessionProgress,
    console,
    flagged_lines,
    readable,
)
from rig.errors import ConfigError, RigError

__all__ = ["FaultHints", "print_status", "register"]

DEFAULT_CONNECT = "tcp://127.0.0.1"
# The options of every command that talks to a running daemon.
Connect = Annotated[
    str, typer.Option("--connect", help="the daemon's control address, tcp://HOST[:PORT]")
]
ServerKey = Annotated[
    Path | None,
    typer.Option(
        "--curve-server-key", help="the daemon's public CURVE certificate (a daemon with keys)"
    ),
]
SecretKey = Annotated[
    Path | None,
    typer.Option(
        "--curve-secret-key",
        help="this client's secret CURVE certificate (its public half in the daemon's clients dir)",
    ),
]


def _daemon_at(connect: str, server_key: Path | None, secret_key: Path | None):
    """The daemon's endpoints, with this client's CURVE keys when given."""
    from orchestrator.wire.endpoints import ClientKeys, Endpoints

    if (server_key is None) != (secret_key is None):
        raise ConfigError(
            "--curve-server-key and --curve-secret-key: give both for a daemon with CURVE "
            "keys, or neither for one on this machine without them"
        )
    keys = None if server_key is None else ClientKeys.load(server_key, secret_key)
    return Endpoints.from_base(connect, keys=keys)


#: `rig status --follow`'s exit status when the session paused.
EXIT_PAUSED = 3


def _stops_following(event: dict) -> bool:
    from orchestrator.client import session_ended, session_paused

    return session_ended(event) or session_paused(event)


def print_status(state: dict) -> None:
    """The daemon's state and its session's fields, one per line."""
    session = state.get("session") or {}
    console.print(f"daemon: [bold]{state.get('state')}[/bold]")
    for key in ("session", "sample", "archive", "committed", "steps", "frames", "fault", "reason"):
        if session.get(key) is not None:
            console.print(escape(f"  {key}: {readable(session[key])}"))
    for line in flagged_lines(session.get("flagged") or {}):
        console.print(escape(f"  {line}"))


class FaultHints:
    """Passes each event on to ``view``; when a fault pauses the session, says what
    happened and what the user can do, with the address of the daemon to do it at.

    Said once per pause: on the fault's state event, or, for a follower that joined
    after the fault (a fault at the first step can come before it subscribed), on the
    first status that shows the session paused with a fault.
    """

    def __init__(self, view, connect: str = DEFAULT_CONNECT):
        self.view = view
        self.connect = connect
        self._said = False

    def __call__(self, event: dict) -> None:
        self.view(event)
        topic = event.get("topic")
        if topic == "daemon":
            self.connect = event["control"]
        elif topic == "state":
            self._said = False
            if event.get("event") == "fault":
                self._say(event)
        elif topic == "status" and event.get("state") == "paused" and not self._said:
            fault = (event.get("session") or {}).get("fault")
            if fault:
                self._say(fault)

    def _say(self, fault: dict) -> None:
        self._said = True
        where = "" if self.connect == DEFAULT_CONNECT else f" --connect {self.connect}"
        console.print(
            escape(
                f"paused: {fault.get('device')} failed at step {fault.get('step')} "
                f"({fault.get('operation')}: {fault.get('detail')}).\n"
                f"  Fix it, then `rig resume{where}` to retry that step, or "
                f"`rig abort{where}` to end the session: committed steps stay in the "
                "archive, and `rig resume ARCHIVE` with a daemon continues it later."
            ),
            style="yellow",
        )


def daemon(
    config: Annotated[
        Path | None, typer.Option("--config", "-c", help="rig config TOML (default rig)")
    ] = None,
    host: Annotated[
        str, typer.Option(help="address to bind; beyond loopback needs CURVE")
    ] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="control port; the next three carry the rest")] = 5570,
    on_fault: Annotated[
        str, typer.Option("--on-fault", help="pause (resume retries the step) or fail")
    ] = "pause",
    curve_secret_key: Annotated[
        Path | None,
        typer.Option(exists=True, dir_okay=False, help="the server's secret CURVE certificate"),
    ] = None,
    curve_clients_dir: Annotated[
        Path | None,
        typer.Option(
            exists=True, file_okay=False, help="folder of the allowed clients' public certs"
        ),
    ] = None,
) -> None:
    """Run the daemon that owns the devices and one session at a time."""
    import zmq
    from pydantic import ValidationError

    from orchestrator.local import run_daemon
    from orchestrator.wire.endpoints import DaemonSettings

    options = {
        "host": host,
        "port": port,
        "on_fault": on_fault,
        "curve_secret_key": curve_secret_key,
        "curve_clients_dir": curve_clients_dir,
    }
    try:
        settings = DaemonSettings(**options)
    except ValidationError as err:
        raise ConfigError(
            "; ".join(
                f"--{str(e['loc'][0]).replace('_', '-')} {e['input']}: {e['msg']}"
                for e in err.errors()
            )
        ) from None
    try:
        run_daemon(
            config,
            settings=settings,
            on_ready=lambda ep: console.print(f"daemon listening on {ep.control}"),
        )
    except zmq.ZMQError as err:
        if err.errno != zmq.EADDRINUSE:
            raise
        raise RigError(
            f"cannot listen on {host} ports {port}–{port + 3}: {err.strerror} (another "
            "`rig daemon` or program holds one); stop it, or give another --port"
        ) from None


def submit(
    plan: Annotated[Path, typer.Argument(help="plan TOML")],
    archive: Annotated[
        Path | None, typer.Option("--archive", help="where to write (default: the plan's)")
    ] = None,
    connect: Connect = DEFAULT_CONNECT,
    server_key: ServerKey = None,
    secret_key: SecretKey = None,
) -> None:
    """Submit a plan to the running daemon."""
    from orchestrator import client

    address = _daemon_at(connect, server_key, secret_key)
    print_status(client.submit(plan, archive=archive, connect=address))


def status(
    follow: Annotated[bool, typer.Option("--follow", "-f", help="keep following")] = False,
    connect: Connect = DEFAULT_CONNECT,
    server_key: ServerKey = None,
    secret_key: SecretKey = None,
) -> None:
    """Show the daemon's session state, or follow it with --follow.

    --follow draws progress until the session ends or pauses; the exit status
    then says how it stopped: 0 the session is done,
    3 it paused (`rig resume` or `rig abort` it), 1 it failed or was aborted,
    or the daemon became unreachable (it stopped answering: killed, or gone).
    Piped, each event is printed as one line as it comes.
    """
    from orchestrator import client

    address = _daemon_at(connect, server_key, secret_key)
    if not follow:
        print_status(client.status(connect=address))
        return
    with SessionProgress() as view:
        hints = FaultHints(view, connect)
        for event in client.follow(address, until=_stops_following):
            hints(event)
    final = client.status(connect=address)
    print_status(final)
    if final.get("state") == "paused":
        raise typer.Exit(EXIT_PAUSED)
    if final.get("state") != "done":
        raise typer.Exit(1)


def pause(
    connect: Connect = DEFAULT_CONNECT, server_key: ServerKey = None, secret_key: SecretKey = None
) -> None:
    """Pause the running session after the current step."""
    from orchestrator import client

    print_status(client.pause(connect=_daemon_at(connect, server_key, secret_key)))


def abort(
    connect: Connect = DEFAULT_CONNECT, server_key: ServerKey = None, secret_key: SecretKey = None
) -> None:
    """Abort the running session; its committed steps stay."""
    from orchestrator import client

    print_status(client.abort(connect=_daemon_at(connect, server_key, secret_key)))


def shutdown(
    connect: Connect = DEFAULT_CONNECT, server_key: ServerKey = None, secret_key: SecretKey = None
) -> None:
    """Stop the daemon cleanly."""
    from orchestrator import client

    print_status(client.shutdown(connect=_daemon_at(connect, server_key, secret_key)))


def resume(
    archive: Annotated[
        Path | None, typer.Argument(help="continue a crashed session from its archive")
    ] = None,
    config: Annotated[
        Path | None,
        typer.Option(
            "--config",
            "-c",
            help="with ARCHIVE: the rig config whose connections to use (devices on new "
            "ports); its geometry must be the recorded one (default: the daemon's config)",
        ),
    ] = None,
    connect: Connect = DEFAULT_CONNECT,
    server_key: ServerKey = None,
    secret_key: SecretKey = None,
) -> None:
    """Resume a paused session, or a crashed one from ARCHIVE.

    With ARCHIVE the daemon runs only the steps the archive has not committed; the
    rig config must describe the rig it recorded (devices may be on other ports).
    """
    from orchestrator import client

    address = _daemon_at(connect, server_key, secret_key)
    print_status(client.resume(archive, config=config, connect=address))


def worker(
    stage: Annotated[
        str,
        typer.Argument(help="live stage(s), comma-separated: stats, register, laser, ps"),
    ],
    connect: Connect = DEFAULT_CONNECT,
    server_key: ServerKey = None,
    secret_key: SecretKey = None,
) -> None:
    """Run live stages on a daemon's frames and push the results back.

    Every worker of a session must run the same stages (frames go round robin).
    Stages other than stats read the session's archive: a worker on another machine
    needs it at the same path (a shared file system). Ctrl-C stops the worker.
    """
    from orchestrator.worker import run_worker

    stop = threading.Event()
    previous = signal.signal(signal.SIGINT, lambda *_: stop.set())
    try:
        done = run_worker(stage, _daemon_at(connect, server_key, secret_key), stop=stop)
    finally:
        signal.signal(signal.SIGINT, previous)
    console.print(f"worker processed {done} frame(s)")


def register(app: typer.Typer) -> None:
    """Add the session commands to ``app``, in the order `rig --help` lists them."""
    for command in (daemon, submit, status, pause, abort, shutdown, resume, worker):
        app.command()(command)
