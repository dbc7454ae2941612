"""CURVE keys: a file that is not the server's secret certificate is refused by name, at
once (nothing left open to hang the exit); a secret certificate serves."""

import pytest
import zmq.auth
from typer.testing import CliRunner

from orchestrator.cli import app
from orchestrator.daemon import DaemonSettings, daemon_thread
from rig.config import default_rig_config
from rig.errors import ConfigError

runner = CliRunner()


@pytest.fixture
def certificates(tmp_path):
    keys, clients = tmp_path / "keys", tmp_path / "clients"
    keys.mkdir()
    clients.mkdir()
    public, secret = zmq.auth.create_certificates(keys, "server")
    (tmp_path / "junk.bin").write_bytes(b"\xff\xfe\x00 not a certificate")
    return {"public": public, "secret": secret, "junk": tmp_path / "junk.bin", "clients": clients}


@pytest.mark.timeout(60)
@pytest.mark.parametrize(
    ("which", "says"),
    [
        ("public", "holds only a public key"),
        ("junk", "not a CURVE certificate"),
    ],
)
def test_rig_daemon_refuses_a_bad_key_file_by_name(certificates, which, says):
    key = certificates[which]
    result = runner.invoke(
        app,
        [
            "daemon",
            "--port",
            "0",
            "--curve-secret-key",
            str(key),
            "--curve-clients-dir",
            str(certificates["clients"]),
        ],
    )
    assert result.exit_code == 2, result.output
    assert f"curve_secret_key {key}" in result.output and says in result.output


@pytest.mark.parametrize("clients", [None, "nowhere"])
def test_a_key_without_a_folder_of_clients_is_refused(certificates, tmp_path, clients):
    settings = DaemonSettings(
        port=0,
        curve_secret_key=certificates["secret"],
        curve_clients_dir=None if clients is None else tmp_path / clients,
    )
    with pytest.raises(ConfigError, match=r"daemon curve_clients_dir .*public certificates"):
        settings.curve_keys()


def test_a_secret_certificate_serves_a_known_client(certificates):
    _, client_secret = zmq.auth.create_certificates(certificates["clients"], "lab")
    settings = DaemonSettings(
        port=0,
        curve_secret_key=certificates["secret"],
        curve_clients_dir=certificates["clients"],
    )
    server_public, _ = zmq.auth.load_certificate(certificates["public"])
    with daemon_thread(default_rig_config(), settings=settings) as endpoints:
        ctx = zmq.Context()
        sock = ctx.socket(zmq.REQ)
        sock.linger = 0
        sock.curve_publickey, sock.curve_secretkey = zmq.auth.load_certificate(client_secret)
        sock.curve_serverkey = server_public
        try:
            sock.connect(endpoints.control)
            sock.send_json({"id": "c1", "command": "status", "args": {}})
            assert sock.poll(5000), "no reply over CURVE"
            reply = sock.recv_json()
        finally:
            sock.close(linger=0)
            ctx.term()
    assert reply["ok"] and reply["result"]["state"] == "idle"
