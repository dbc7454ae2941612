"""CURVE keys: a file that is not the server's secret certificate is refused by name, at
once (nothing left open to hang the exit); a secret certificate serves."""

import os
from pathlib import Path

import pytest
import zmq.auth
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from orchestrator.cli import app
from orchestrator.local import daemon_thread
from orchestrator.wire.endpoints import ClientKeys, DaemonSettings, read_certificate
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


def _daemon(secret, clients):
    args = ["daemon", "--port", "0", "--curve-secret-key", str(secret)]
    return runner.invoke(app, [*args, "--curve-clients-dir", str(clients)])


@pytest.fixture
def fifo(tmp_path):
    path = tmp_path / "fifo.key"
    os.mkfifo(path)
    return path


@pytest.mark.timeout(60)
@pytest.mark.parametrize("which", ["/dev/zero", "fifo", "huge"])
def test_a_key_file_that_is_no_small_regular_file_is_refused_unread(
    certificates, fifo, tmp_path, which
):
    # /dev/zero took the daemon to 6.5 GB and hung it; a FIFO hung daemon and client.
    huge = tmp_path / "huge.key"
    huge.write_bytes(b"public-key = " + b"x" * 10_000_000)
    key = {"/dev/zero": Path("/dev/zero"), "fifo": fifo, "huge": huge}[which]
    says = "more than a CURVE certificate holds" if which == "huge" else "not a regular file"
    result = _daemon(key, certificates["clients"])
    assert result.exit_code == 2, result.output
    said = " ".join(result.output.split())
    assert f"curve_secret_key {key}" in said and says in said
    client = ["status", "--curve-server-key", str(key)]
    result = runner.invoke(app, [*client, "--curve-secret-key", str(certificates["secret"])])
    assert result.exit_code == 2, result.output
    assert f"--curve-server-key {key}" in " ".join(result.output.split())
    with pytest.raises(ConfigError, match=r"not a regular file|more than a CURVE"):
        ClientKeys.load(certificates["public"], key)


@pytest.mark.timeout(60)
@pytest.mark.parametrize("bad", ["garbled", "fifo"])
def test_one_bad_client_certificate_is_refused_at_start_naming_it(certificates, bad):
    zmq.auth.create_certificates(certificates["clients"], "good")
    wrong = certificates["clients"] / "wrong.key"
    if bad == "fifo":
        os.mkfifo(wrong)
    else:
        wrong.write_text('curve\n    public-key = "not z85 at all"\n')
    result = _daemon(certificates["secret"], certificates["clients"])
    assert result.exit_code == 2, result.output
    said = " ".join(result.output.split())
    assert f"client certificate {wrong}" in said


_Z85 = "0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ.-:+=^!/*?&<>()[]{}@%$#"
_z85 = st.text(_Z85, min_size=38, max_size=42)
_lines = st.one_of(
    st.builds(lambda k, v: f'    {k} = "{v}"', st.sampled_from(["public-key", "secret-key"]), _z85),
    st.sampled_from(["metadata", "curve", "#   comment", "public-key", "secret-key =", ""]),
    st.text(max_size=60),
)


@settings(
    max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    body=st.lists(_lines, max_size=8).map(lambda lines: "\n".join(lines).encode())
    | st.binary(max_size=300)
)
def test_any_key_file_is_read_or_refused_by_name(tmp_path, body):
    # Certificates cut short, garbled, with keys of the wrong length, random bytes.
    path = tmp_path / "fuzz.key"
    path.write_bytes(body)
    try:
        public, secret = read_certificate(path, "a key")
    except ConfigError as err:
        refused = str(err)
    else:
        refused = None
        assert len(public) == 40 and (secret is None or len(secret) == 40)
        assert public in body
    assert refused is None or f"a key {path}: not a CURVE certificate" in refused
