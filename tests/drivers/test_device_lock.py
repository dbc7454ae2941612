"""One owner per device: a second open of a connection is refused, naming the holder."""

import os
import stat
import subprocess
import sys
import tempfile

import pytest

from drivers import open_device
from drivers._lock import DeviceLock, serial_lock_key
from drivers.errors import DeviceError
from drivers.modbus import ModbusTurntable
from rig.clock import VirtualClock
from rig.config import default_rig_config
from rig.devices import ModbusDrive
from sim.peers import DynamixelBusPeer
from sim.world import World

AXIS = default_rig_config().turntable.axis


@pytest.fixture(autouse=True)
def lock_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("BTFRIG_LOCK_DIR", str(tmp_path / "locks"))
    return tmp_path / "locks"


def _drive(port: int, unit_id: int = 1) -> ModbusTurntable:
    # the Modbus client connects on the first request: opening takes only the lock
    return ModbusTurntable(ModbusDrive(port=port, unit_id=unit_id), axis=AXIS, clock=VirtualClock())


def test_a_second_open_of_one_connection_is_refused_until_the_first_closes():
    first = _drive(15020)
    with pytest.raises(
        DeviceError, match=rf"turntable: open failed: .*in use by process {os.getpid()}"
    ):
        _drive(15020)
    first.close()
    again = _drive(15020)  # released at close
    again.close()


def test_other_connections_open_side_by_side():
    devices = [_drive(15020), _drive(15021), _drive(15020, unit_id=2)]
    for device in devices:
        device.close()


def test_a_lock_held_by_another_process_names_its_pid(lock_dir):
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys; from drivers._lock import DeviceLock\n"
            "lock = DeviceLock('modbus tcp://127.0.0.1:15020 unit 1', device='other daemon')\n"
            "print('locked', flush=True); sys.stdin.read()",
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "BTFRIG_LOCK_DIR": str(lock_dir)},
    )
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(DeviceError, match=rf"in use by process {holder.pid} \(lock "):
            _drive(15020)
    finally:
        holder.communicate("", timeout=10)  # the holder exits: the kernel drops its lock
    _drive(15020).close()


def test_two_names_of_one_serial_port_are_one_device(tmp_path):
    link = tmp_path / "ttyArc"
    link.symlink_to("/dev/null")
    assert serial_lock_key(str(link)) == serial_lock_key("/dev/null")
    lock = DeviceLock(serial_lock_key("/dev/null"), device="light arc")
    with pytest.raises(DeviceError, match="light arc: open failed: serial:/dev/null is in use"):
        DeviceLock(serial_lock_key(str(link)), device="light arc")
    lock.release()
    lock.release()  # idempotent


def test_a_second_daemon_cannot_open_the_light_arc():
    world = World(default_rig_config(), VirtualClock())
    with DynamixelBusPeer(world) as peer:
        section = peer.connect(world.config.light_arc)
        arc = open_device("light_arc", section, clock=world.clock)
        try:
            with pytest.raises(DeviceError, match=r"light arc: open failed: dynamixel serial:"):
                open_device("light_arc", section, clock=world.clock)
            arc.home()  # the first owner still drives it
        finally:
            arc.close()


@pytest.mark.parametrize("planted", ["symlink", "hard link"])
def test_a_link_planted_in_the_lock_folder_is_refused_and_its_target_untouched(
    lock_dir, tmp_path, planted
):
    # What another user can do in a shared folder: point the next lock file at a victim.
    lock_dir.mkdir()
    victim = tmp_path / "victim.txt"
    victim.write_text("the victim's data")
    lock_file = lock_dir / "modbus_tcp_127.0.0.1_15020_unit_1.lock"
    (os.symlink if planted == "symlink" else os.link)(victim, lock_file)
    with pytest.raises(
        DeviceError, match=r"turntable: open failed: lock file .*unit_1\.lock is a link"
    ):
        _drive(15020)
    assert victim.read_text() == "the victim's data"


@pytest.fixture
def default_lock_dir(tmp_path, monkeypatch):
    """The default lock folder, under a private <tmp>."""
    monkeypatch.delenv("BTFRIG_LOCK_DIR")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    return tmp_path / f"btfrig-locks-{os.geteuid()}"


def test_the_default_lock_folder_is_private(default_lock_dir):
    _drive(15020).close()
    assert stat.S_IMODE(default_lock_dir.stat().st_mode) == 0o700


@pytest.mark.parametrize(
    ("setup", "named"),
    [
        (lambda d: (d.mkdir(), d.chmod(0o777)), "writable by others"),
        (lambda d: (d.mkdir(), os.chown(d, 65534, 65534)), "owned by user id 65534"),
        (lambda d: (d.with_name("x").mkdir(), d.symlink_to("x")), "a symbolic link"),
    ],
)
def test_a_default_lock_folder_someone_else_prepared_is_refused(default_lock_dir, setup, named):
    setup(default_lock_dir)
    with pytest.raises(DeviceError, match=rf"lock folder .* is {named}"):
        _drive(15020)
    assert not any(default_lock_dir.iterdir())
