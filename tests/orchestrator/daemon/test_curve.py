"""Remote operation: a daemon with CURVE keys, a worker and clients over TCP with theirs."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
import zmq.auth
from typer.testing import CliRunner

from orchestrator.cli import app
from orchestrator.client import DaemonClient, DaemonUnreachable, wait_for_state
from orchestrator.wire.endpoints import ClientKeys, Endpoints
from rig.errors import ConfigError
from tests.orchestrator.daemon.conftest import LAMP_PLAN, running_daemon, running_workers


@pytest.fixture
def certificates(tmp_path):
    """The daemon's key pair, an allowed client's and a stranger's (zmq.auth files)."""
    for folder in ("server", "clients", "client", "stranger"):
        (tmp_path / folder).mkdir()
    server_public, server_secret = zmq.auth.create_certificates(tmp_path / "server", "daemon")
    client_public, client_secret = zmq.auth.create_certificates(tmp_path / "client", "lab-pc")
    _, stranger_secret = zmq.auth.create_certificates(tmp_path / "stranger", "stranger")
    (tmp_path / "clients" / "lab-pc.key").write_bytes(Path(client_public).read_bytes())
    return {
        "daemon": {"curve_secret_key": server_secret, "curve_clients_dir": tmp_path / "clients"},
        "client": ClientKeys.load(server_public, client_secret),
        "stranger": ClientKeys.load(server_public, stranger_secret),
        "files": (server_public, client_secret),
    }


def test_worker_and_client_run_a_session_over_curve(config, rig, certificates, tmp_path):
    with running_daemon(config, rig, **certificates["daemon"]) as plain:
        assert plain.control.startswith("tcp://127.0.0.1:")
        endpoints = replace(plain, keys=certificates["client"])
        with running_workers(endpoints, n=1) as counts:
            with DaemonClient(endpoints) as client:
                client.request("submit", plan_toml=LAMP_PLAN, archive=str(tmp_path / "s.zarr"))
            done = wait_for_state(endpoints, ("done",), settled=True)
        frames = done["session"]["frames"]
        assert frames > 0 and done["stream"]["processed"] == frames
    assert counts["w0"] == frames  # every frame went through the encrypted worker


@pytest.mark.parametrize("who", ["no keys", "stranger"])
def test_a_client_without_allowed_keys_gets_no_answer(config, rig, certificates, who):
    with running_daemon(config, rig, **certificates["daemon"]) as plain:
        endpoints = plain if who == "no keys" else replace(plain, keys=certificates[who])
        with (
            DaemonClient(endpoints, timeout_s=0.3, retries=0) as client,
            pytest.raises(DaemonUnreachable, match="curve"),
        ):
            client.request("status")


def test_rig_status_takes_the_client_keys(config, rig, certificates):
    server_public, client_secret = certificates["files"]
    runner = CliRunner()
    with running_daemon(config, rig, **certificates["daemon"]) as endpoints:
        connect = ["--connect", endpoints.control]
        keys = ["--curve-server-key", server_public, "--curve-secret-key", client_secret]
        result = runner.invoke(app, ["status", *connect, *keys])
        assert result.exit_code == 0, result.output
        assert "daemon: idle" in result.output
    half = runner.invoke(app, ["status", *connect, "--curve-server-key", server_public])
    assert half.exit_code == 2 and "give both" in half.output
    swapped = ["--curve-server-key", server_public, "--curve-secret-key", server_public]
    result = runner.invoke(app, ["worker", "stats", *connect, *swapped])
    assert result.exit_code == 2 and "only a public key" in result.output


def test_a_remote_address_needs_client_keys(certificates):
    with pytest.raises(ConfigError, match="curve-server-key"):
        Endpoints.from_base("tcp://10.0.0.2")
    remote = Endpoints.from_base("tcp://10.0.0.2:6000", keys=certificates["client"])
    assert (remote.control, remote.results) == ("tcp://10.0.0.2:6000", "tcp://10.0.0.2:6003")
