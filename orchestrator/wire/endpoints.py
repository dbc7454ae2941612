"""Where the daemon listens, and the rule that remote use needs CURVE keys.

The four sockets sit on consecutive ports from a base port: control (base),
events (base + 1), frames (base + 2), results (base + 3). ``Endpoints``
holds their URLs; ``DaemonSettings`` is the daemon's own (closed) settings.
"""

from __future__ import annotations

import ipaddress
import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Literal
from urllib.parse import urlsplit

from pydantic import BaseModel, ConfigDict, Field

from rig.errors import ConfigError

__all__ = [
    "DEFAULT_PORT",
    "ClientKeys",
    "DaemonSettings",
    "Endpoints",
    "is_loopback",
    "read_certificate",
]

DEFAULT_PORT = 5570
_ROLES = ("control", "events", "frames", "results")


#: Largest certificate file read (zmq.auth writes about 300 bytes).
_MAX_CERTIFICATE_BYTES = 64 * 1024
_Z85_KEY = re.compile(rb"[0-9a-zA-Z.\-:+=^!/*?&<>()\[\]{}@%$#]{40}")
_HOW = "make a pair with zmq.auth.create_certificates"


def read_certificate(path: Path, what: str) -> tuple[bytes, bytes | None]:
    """The (public, secret or None) z85 CURVE keys of the certificate file ``path``.

    Only a regular file of at most 64 KiB is read (never a device such as
    /dev/zero, nor a FIFO that would block); a ``ConfigError`` names ``what``
    and the file otherwise, as it does a file that holds no valid public key.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as err:
        raise ConfigError(f"{what} {path}: cannot be read ({err.strerror})") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise ConfigError(
                f"{what} {path}: not a regular file (a device, a FIFO or a folder); "
                f"a CURVE certificate is a small text file; {_HOW}"
            )
        if info.st_size > _MAX_CERTIFICATE_BYTES:
            raise ConfigError(
                f"{what} {path}: {info.st_size} bytes, more than a CURVE certificate "
                f"holds (at most {_MAX_CERTIFICATE_BYTES}); {_HOW}"
            )
        text = os.read(fd, _MAX_CERTIFICATE_BYTES)
    finally:
        os.close(fd)
    keys: dict[bytes, bytes] = {}
    for line in text.splitlines():  # the format zmq.auth.load_certificate reads
        name, sep, value = line.strip().partition(b"=")
        if sep and name.strip() in (b"public-key", b"secret-key"):
            keys.setdefault(name.strip(), value.strip(b" \t'\""))
    public, secret = keys.get(b"public-key"), keys.get(b"secret-key")
    for key in (public, secret):
        if key is not None and not _Z85_KEY.fullmatch(key):
            public = None
    if public is None:
        raise ConfigError(
            f"{what} {path}: not a CURVE certificate (no public-key line with 40 "
            f"Z85 characters); {_HOW}"
        )
    return public, secret


def _certificate(path: Path, option: str, *, secret: bool) -> tuple[bytes, bytes | None]:
    public, secret_key = read_certificate(path, option)
    if secret and secret_key is None:
        raise ConfigError(
            f"{option} {str(path)!r} holds only a public key; give the secret certificate "
            "(the .key_secret file zmq.auth.create_certificates wrote)"
        )
    return public, secret_key


@dataclass(frozen=True)
class ClientKeys:
    """A client's CURVE keys for a daemon that has them: the daemon's public key and
    this client's key pair (z85), whose public half is in the daemon's clients folder."""

    server_public: bytes
    public: bytes
    secret: bytes

    @classmethod
    def load(cls, server_key: Path, secret_key: Path) -> ClientKeys:
        """From the daemon's public certificate and this client's secret certificate."""
        server_public, _ = _certificate(server_key, "--curve-server-key", secret=False)
        public, secret = _certificate(secret_key, "--curve-secret-key", secret=True)
        return cls(server_public, public, secret)

    def apply(self, sock) -> None:
        """Make ``sock`` (before it connects) a CURVE client of the daemon."""
        sock.curve_serverkey = self.server_public
        sock.curve_publickey = self.public
        sock.curve_secretkey = self.secret


@dataclass(frozen=True)
class Endpoints:
    """The URLs of the daemon's control, events, frames and results sockets, and the
    keys a client connects with (None: plain sockets, loopback only)."""

    control: str
    events: str
    frames: str
    results: str
    keys: ClientKeys | None = None

    def secure(self, sock) -> None:
        """Apply the client keys, if any, to ``sock`` before it connects."""
        if self.keys is not None:
            self.keys.apply(sock)

    @classmethod
    def from_base(
        cls, url: str = f"tcp://127.0.0.1:{DEFAULT_PORT}", *, keys: ClientKeys | None = None
    ) -> Endpoints:
        """``tcp://HOST[:BASE]`` → the four sockets on ports BASE … BASE + 3.

        A host beyond loopback needs ``keys``: a daemon listens there only with CURVE.
        """
        parts = urlsplit(url)
        try:
            port = parts.port
        except ValueError:
            port = -1
        if parts.scheme != "tcp" or not parts.hostname or port == -1:
            raise ConfigError(
                f"daemon address {url!r}: use tcp://HOST or tcp://HOST:PORT "
                f"(PORT = the control port, default {DEFAULT_PORT})"
            )
        base = DEFAULT_PORT if port is None else port
        if not 1 <= base <= 65532:
            raise ConfigError(f"daemon address {url!r}: port {base} must be in 1..65532")
        host = parts.hostname
        if keys is None and not is_loopback(host):
            raise ConfigError(
                f"daemon address {url!r} is beyond this machine, where the daemon speaks "
                "CURVE only: give --curve-server-key (its public certificate) and "
                "--curve-secret-key (this client's secret certificate)"
            )
        host = f"[{host}]" if ":" in host else host
        return cls(*(f"tcp://{host}:{base + i}" for i in range(4)), keys=keys)


def is_loopback(host: str) -> bool:
    """True for localhost and loopback addresses (127.0.0.0/8, ::1)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


class DaemonSettings(BaseModel):
    """How the daemon listens and streams. Port 0: every socket on a free port."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    host: str = "127.0.0.1"
    port: int = Field(DEFAULT_PORT, ge=0, le=65532, description="control port; 0 = any free")
    curve_secret_key: Path | None = Field(
        None, description="the server's secret certificate (zmq.auth.create_certificates)"
    )
    curve_clients_dir: Path | None = Field(
        None, description="folder of the public certificates of allowed clients"
    )
    on_fault: Literal["pause", "fail"] = "pause"
    status_interval_s: float = Field(1.0, gt=0, description="status snapshot period")
    resend_after_s: float = Field(10.0, gt=0, description="re-send a frame without result")
    worker_timeout_s: float = Field(3.0, gt=0, description="a silent worker counts as gone")
    max_in_flight: int = Field(256, ge=1, description="frames sent and not yet processed")
    drain_timeout_s: float = Field(60.0, ge=0, description="wait for workers at the end")

    def bind_urls(self) -> dict[str, str]:
        """The URL each socket binds (``tcp://host:*`` for any free port)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return {
            role: f"tcp://{host}:{'*' if self.port == 0 else self.port + i}"
            for i, role in enumerate(_ROLES)
        }

    def check_exposure(self) -> None:
        """Refuse to listen beyond loopback without CURVE keys."""
        if is_loopback(self.host):
            return
        if self.curve_secret_key is None or self.curve_clients_dir is None:
            raise ConfigError(
                f"daemon host {self.host!r} is not a loopback address: listening beyond this "
                "machine needs CURVE encryption; set curve_secret_key (the server's "
                "certificate, made by zmq.auth.create_certificates) and curve_clients_dir "
                "(allowed clients' public certificates), or use host = '127.0.0.1'"
            )
        for name in ("curve_secret_key", "curve_clients_dir"):
            path = getattr(self, name)
            if not path.exists():
                raise ConfigError(f"daemon {name} = {str(path)!r}: no such file or folder")

    def curve_keys(self) -> tuple[bytes, bytes] | None:
        """The server's (public, secret) CURVE keys from ``curve_secret_key``; None without
        one. A file that is not a secret certificate, or no folder of clients'
        certificates, is a ``ConfigError`` naming it."""
        path = self.curve_secret_key
        if path is None:
            return None
        public, secret = read_certificate(path, "daemon curve_secret_key")
        if secret is None:
            raise ConfigError(
                f"daemon curve_secret_key {path}: holds only a public key; the daemon needs "
                f"its secret certificate; {_HOW} and give its .key_secret file"
            )
        clients = self.curve_clients_dir
        if clients is None or not clients.is_dir():
            given = "is not set" if clients is None else f"{str(clients)!r} is not a folder"
            raise ConfigError(
                f"daemon curve_clients_dir {given}: with a CURVE key the daemon admits only "
                "the clients whose public certificates are in that folder"
            )
        # The authenticator reads every *.key there (as glob does, not hidden ones); one bad
        # file would make it refuse every client, so each is checked before it starts.
        for client in sorted(clients.glob("*.key")):
            if not client.name.startswith("."):
                read_certificate(client, "daemon curve_clients_dir: client certificate")
        return public, secret
