"""The README's three-shell session records a good MDF: `rig sim --speed 10` (the sheet
tilts ten times faster than the daemon's real clock), `rig daemon`, `rig submit`. Frames
the sheet ran away from are flagged and taken again at their tilts, `rig status` and `rig
process` say so, and the MDF's coverage is the virtual-time run's (`rig run --sim`)
within 2 %."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from orchestrator import client
from rig.archive import Archive
from rig.config import RigConfig
from rig.frame_check import scan_tilts_deg, tilt_tolerance_deg
from tests.integration.test_cli_processes import (
    RIG,
    ROOT,
    _cli,
    _free_base_port,
    _start,
    _stop,
    _wait,
    _wait_up,
)

# Three processes rendering 121 laser frames at the README's scale, some twice, and the
# same scan in virtual time: minutes on a loaded machine.
pytestmark = [pytest.mark.slow, pytest.mark.timeout(1200)]

# The first scan of the README's demo plan: the frontal view, the laser at θ 45°, φ 0.
PLAN = """
[sample]
name = "scan"
[captures.mdf]
views = [[0, 0]]
laser_locations = [[45, 0]]
[exposure]
laser_exposure_s = 0.005
"""


def _seen_fraction(archive) -> float:
    with Archive.open(archive) as arch:
        return float(np.mean(arch.material["mdf"]["distance_mm"][...] >= 0))


def _long(*args: str) -> subprocess.CompletedProcess:
    """``_cli`` for the commands that capture or process a whole scan."""
    return subprocess.run([RIG, *args], cwd=ROOT, capture_output=True, text=True, timeout=600)


def _processed(archive) -> str:
    done = _long("process", str(archive), "--stages", "mdf", "--workers", "1")
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


def test_the_readme_three_shell_session_records_the_virtual_time_mdf(tmp_path):
    scene = str(ROOT / "examples/scenes/default.toml")  # the README's scene, as it is
    (tmp_path / "plan.toml").write_text(PLAN)
    virtual = tmp_path / "virtual.zarr"
    ran = _long("run", str(tmp_path / "plan.toml"), "--sim", scene, "--archive", str(virtual))
    assert ran.returncode == 0, ran.stdout + ran.stderr

    config, archive = tmp_path / "sim-rig.toml", tmp_path / "s.zarr"
    connect = f"tcp://127.0.0.1:{_free_base_port()}"
    sim = _start("sim", scene, "--config-out", str(config), "--speed", "10")
    daemon = None
    try:
        _wait(lambda: config.exists() or sim.poll() is not None, "the sim's rig config")
        assert sim.poll() is None, _stop(sim)
        daemon = _start("daemon", "--config", str(config), "--port", connect.rsplit(":", 1)[1])
        _wait_up(daemon, connect)
        submitted = _cli("submit", str(tmp_path / "plan.toml"), "--archive", str(archive),
                         "--connect", connect)  # fmt: skip
        assert submitted.returncode == 0, submitted.stdout + submitted.stderr
        final = client.wait_for_state(connect, client.TERMINAL_STATES, settled=True, timeout_s=600)
        assert final["state"] == "done", final
        status = _cli("status", "--connect", connect)
        assert _cli("shutdown", "--connect", connect).returncode == 0
    finally:
        for proc in (daemon, sim):
            if proc is not None:
                _stop(proc)

    with Archive.open(archive) as arch:
        (step,) = arch.step_table()
        (scan,) = arch.events("scan")
        rig = RigConfig.model_validate(arch.rig_config)
    # the sheet outruns a camera rendered in real time: frames were flagged, every one
    # taken again at its tilt, and the session and the processing both report them
    flagged = final["session"]["flagged"]
    assert flagged["frames"] == len(step.flags) > 0
    assert flagged["left_out"] == 0 and all(flag.recaptured for flag in step.flags)
    assert f"flagged: {len(step.flags)} frame(s)" in status.stdout
    assert f"(steps {step.index})" in status.stdout
    assert "laser tilt read back" in status.stdout
    # every frame's tilt is its plan's, as in virtual time (a scan sweeps ±sweep_deg / 2)
    tilts = np.array(scan.payload["tilts_deg"])
    half = rig.laser.sweep_deg / 2
    planned = scan_tilts_deg(rig, (-half, half), len(tilts))
    assert np.abs(tilts - planned).max() <= tilt_tolerance_deg(rig, planned)

    processed = _processed(archive)
    assert f"flagged: {len(step.flags)} frame(s)" in processed
    _processed(virtual)
    seen, expected = _seen_fraction(archive), _seen_fraction(virtual)
    assert expected > 0.5  # the virtual-time scan sees most of the sample
    assert seen == pytest.approx(expected, rel=0.02)
