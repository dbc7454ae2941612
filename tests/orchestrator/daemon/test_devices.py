"""``build_devices`` opens every role through the registry, on the simulator's peers."""

import numpy as np
import pytest

from drivers.errors import DeviceError
from orchestrator.daemon import build_devices
from rig.clock import VirtualClock
from rig.config import default_rig_config
from rig.devices import DEVICE_ROLES, Retry
from sim.peers import CameraServer, start_peer
from sim.world import World

FAST = Retry(timeout_s=0.2, retries=1, backoff_s=0.01)


@pytest.fixture
def world():
    return World(default_rig_config(), VirtualClock())


@pytest.fixture
def peers(world):
    started = {role: start_peer(role, getattr(world.config, role), world) for role in DEVICE_ROLES}
    yield started
    for peer in started.values():
        peer.stop()


def _on_peers(config, peers, **laser_device):
    update = {}
    for role, peer in peers.items():
        section = peer.connect(getattr(config, role))
        changes = {"retry": FAST, **(laser_device if role == "laser" else {})}
        update[role] = section.model_copy(
            update={"device": section.device.model_copy(update=changes)}
        )
    cameras = config.camera_arc.model_copy(update={"cameras": config.camera_arc.cameras[:1]})
    return config.model_copy(update={**update, "camera_arc": cameras})


def _with_camera_server(config, server):
    """``config`` whose one camera is served by the camera ``server``."""
    spec = config.camera_arc.cameras[0]
    connection = spec.connection.model_copy(update={"url": server.url})
    cam = config.camera_arc.model_copy(
        update={"cameras": (spec.model_copy(update={"connection": connection}),)}
    )
    return config.model_copy(update={"camera_arc": cam})


def _render(camera_id, snapshot, exposure_s):
    raise AssertionError("no frame is captured here")


def test_every_role_opens_and_a_second_daemon_is_refused(world, peers):
    with CameraServer(world, _render) as cameras:
        config = _with_camera_server(_on_peers(world.config, peers), cameras)
        devices = build_devices(config, clock=world.clock)
        try:
            devices.home(laser=True)
            moved = devices.move(turntable_deg=90.0, arc_deg=20.0)
            with pytest.raises(
                DeviceError, match=r"turntable: open failed: .* is in use by process"
            ):
                build_devices(config, clock=world.clock)
        finally:
            devices.close()
    assert moved == pytest.approx({"turntable_deg": 90.0, "arc_deg": 20.0}, abs=0.05)
    snap = world.snapshot()
    assert (snap.turntable_deg, snap.arc_deg) == pytest.approx((90.0, 20.0), abs=0.05)


def test_a_device_that_fails_to_open_closes_those_opened_before(world, peers):
    broken = _on_peers(world.config, peers, serial_port="/dev/rfcomm-none")
    with pytest.raises(DeviceError, match=r"laser brick \(serial /dev/rfcomm-none\): open failed"):
        build_devices(broken, clock=world.clock)
    # the turntable, arc and lamp bank were closed again: their locks are free
    fixed = _on_peers(world.config, peers)
    devices = build_devices(fixed, clock=world.clock, laser=True)
    devices.close()


def test_a_virtex_stage_opens_its_lamps_and_camera_and_never_moves():
    from sim.rig import SimulatedRig
    from sim.scene import load_scene

    clock = VirtualClock()
    with SimulatedRig(load_scene("examples/scenes/virtex.toml"), clock=clock) as sim:
        devices = build_devices(sim.rig_config(), clock=clock, laser=False)
        try:
            assert devices.turntable is None and devices.arc is None
            devices.home(laser=False)
            assert devices.move(turntable_deg=0.0, arc_deg=0.0) == {}
            with pytest.raises(DeviceError, match=r"virtex rig has no turntable or arc"):
                devices.move(turntable_deg=30.0, arc_deg=0.0)
            devices.lamp("lamp5", True)
            assert devices.telemetry() == {"lamps_on": ["lamp5"]}
            devices.all_off()
        finally:
            devices.close()


def _dark(camera_id, snapshot, exposure_s):
    spec = default_rig_config().camera(camera_id)
    return np.zeros((spec.height, spec.width, spec.channels), dtype=np.uint8)


@pytest.mark.parametrize(("half_sweep_deg", "step_deg"), [(6.0, 2.0), (6.0, 0.5), (1.0, 0.05)])
def test_a_scan_spreads_its_frames_over_the_whole_sweep(world, peers, half_sweep_deg, step_deg):
    """A coarse step covers the sweep from end to end; a step finer than the sheet
    moves between frames at the camera's rate (1°/s at 7.5 Hz) is taken at that rate."""
    with CameraServer(world, _dark) as cameras:
        config = _with_camera_server(_on_peers(world.config, peers), cameras)
        spec = config.camera_arc.cameras[0]
        devices = build_devices(config, clock=world.clock)
        try:
            devices.home(laser=True)
            frames = round(2 * half_sweep_deg / step_deg) + 1
            scan = devices.scan(
                [spec.id], tilt_deg=(-half_sweep_deg, half_sweep_deg), frames=frames,
                exposure_s=0.001,
            )  # fmt: skip
        finally:
            devices.close()
    tilts = scan.tilts_deg
    assert scan.flags == ()  # the camera keeps up with the sheet: every frame matches
    spacing = max(step_deg, 1 / 7.5)
    moving = round(2 * half_sweep_deg / spacing)
    assert tilts[0] == pytest.approx(-half_sweep_deg, abs=0.05)
    # read back through the tacho: one count is 1/24°
    assert np.diff(tilts[: moving + 1]) == pytest.approx(np.full(moving, spacing), abs=0.05)
    assert tilts[-1] == pytest.approx(half_sweep_deg, abs=0.05)


def _fast_sheet_world(speedup: float) -> World:
    """A world whose sheet tilts ``speedup`` times faster than the daemon's config says:
    what a simulator run with ``--speed`` does to a daemon on real time, and a real rig
    whose camera is slower than its sweep."""
    config = default_rig_config()
    laser = config.laser.model_copy(
        update={"sweep_speed_deg_s": config.laser.sweep_speed_deg_s * speedup}
    )
    return World(config.model_copy(update={"laser": laser}), VirtualClock())


def test_frames_the_sheet_ran_away_from_are_flagged_and_taken_again_at_their_tilt():
    """The sheet sweeps 10× faster than planned: the frames of the sweep land past
    their tilts; each is flagged naming the tilt read back, taken again with the sheet
    held at its planned tilt, and the scan ends with every frame at its plan."""
    from rig.frame_check import scan_tilts_deg, tilt_tolerance_deg

    world = _fast_sheet_world(10.0)
    started = {role: start_peer(role, getattr(world.config, role), world) for role in DEVICE_ROLES}
    try:
        with CameraServer(world, _dark) as cameras:
            # the daemon's config: the sheet's planned speed, 1°/s
            config = _with_camera_server(_on_peers(default_rig_config(), started), cameras)
            spec = config.camera_arc.cameras[0]
            devices = build_devices(config, clock=world.clock)
            try:
                devices.home(laser=True)
                scan = devices.scan([spec.id], tilt_deg=(-3.0, 3.0), frames=31, exposure_s=0.005)
            finally:
                devices.close()
    finally:
        for peer in started.values():
            peer.stop()
    planned = scan_tilts_deg(config, (-3.0, 3.0), 31)
    assert len(scan.frames[spec.id]) == 31
    tilts = np.array(scan.tilts_deg)
    assert np.abs(tilts - planned).max() <= tilt_tolerance_deg(config, planned)
    flagged = sorted({flag.sub for flag in scan.flags})
    assert len(flagged) > 20  # the sheet outran the camera for most of the sweep
    # taken again with the sheet held: at the plan within the tacho's resolution (1/24°)
    assert tilts[flagged] == pytest.approx(planned[flagged], abs=1 / 48 + 1e-9)
    assert all(flag.recaptured and flag.camera == spec.id for flag in scan.flags)
    first = min(scan.flags, key=lambda flag: flag.sub)
    assert first.reason.startswith("laser tilt read back")
    assert f"planned {planned[first.sub]:.3f}°" in first.reason
