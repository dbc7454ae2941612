"""`rig process --stages ps` on sessions recorded against the simulated rig, checked against
the simulator's ray-cast truth on the texel grid.

The whole chain runs: real drivers → archive → marker registration of every frame onto the
texel grid → near-lamp photometric stereo with the lamp positions from the recorded arc and
turntable angles → integration. Tolerances (bumps sample, 12 lamps at θ = 45°, 128² texels
of 0.78 mm, frames at half the rig's resolution with 2×2 area sampling):
without shadows mean angular error < 1°, 95th percentile < 2.5°, albedo proportional to the
truth within 0.5 % (median), height RMSE < 0.1 mm; with cast shadows the
robust solver stays within 2° mean and beats plain least squares.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from orchestrator.cli import app
from orchestrator.local import run_local
from processing.offline import PsStage, StageFailed, run_stages
from rig.clock import VirtualClock
from rig.material import read_material
from sim import Simulator
from sim.rig import SimulatedRig
from sim.scene import scene_from_dict
from tests.processing.photometric.flat_truth import low_frequency_std, texel_truth_over_footprints

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow

SIZE = 128
PLAN = """
[sample]
name = "ps"
[captures.ps]
views = [[0, 0]]
lights = {theta_deg = 45, count = 12}
[exposure]
exposure_s = 0.05
"""


def _scene(effects, **sample):
    data = tomllib.loads(Path("examples/scenes/bumps.toml").read_text())
    data["render"] = {"scale": 0.5, "supersample": 2}
    data["effects"] = effects
    data["sample"].update(sample)
    return scene_from_dict(data)


def _record(scene, tmp_path) -> Path:
    (tmp_path / "plan.toml").write_text(PLAN)
    archive = tmp_path / "ps.zarr"
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as sim:
        final = run_local(tmp_path / "plan.toml", sim.rig_config(), archive=archive, clock=clock)
    assert final["state"] == "done", final
    return archive


@pytest.fixture(scope="module")
def plain(tmp_path_factory):
    scene = _scene([])
    with Simulator(scene) as sim:
        truth = sim.texel_truth(SIZE)
    return _record(scene, tmp_path_factory.mktemp("plain")), truth


def _view(archive):
    (view,) = read_material(archive).ps.values()
    return {k: getattr(view, k) for k in ("normals", "albedo", "valid", "reason", "height_mm")}


def _angular_error_deg(normals, truth):
    return np.degrees(np.arccos(np.clip(np.sum(normals * truth, axis=-1), -1.0, 1.0)))


def test_normals_albedo_and_height_match_the_ray_cast_truth(plain):
    archive, truth = plain
    (run,) = run_stages(archive, [PsStage(size=SIZE)])
    assert run.items == 1 and run.summary["valid_fraction"] > 0.99
    assert read_material(archive).frontal_ps().view_deg[0] < 0.5  # the plan's view (0, 0)
    got = _view(archive)
    assert all(np.isfinite(v).all() for v in got.values())
    err = _angular_error_deg(got["normals"], truth.normals)[got["valid"]]
    assert err.mean() < 1.0 and np.percentile(err, 95) < 2.5, (err.mean(), np.percentile(err, 95))
    # albedo up to the unknown lamp-power scale: measured / true is one constant, except
    # at the checker's edges (a texel averages both colours, the truth is its centre's)
    # and on the recess border ring
    inner = (slice(1, -1), slice(1, -1))
    ratio = (got["albedo"] / np.maximum(truth.albedo, 1e-6))[inner][got["valid"][inner]]
    deviation = np.abs(ratio / np.median(ratio) - 1.0)
    assert np.median(deviation) < 0.005 and np.percentile(deviation, 75) < 0.02
    # height up to its offset (both have the top at 0; the integrator's reference differs)
    dz = got["height_mm"] - truth.height
    rmse = np.sqrt(np.mean((dz - dz.mean()) ** 2))
    assert rmse < 0.1, rmse  # mm, bumps 1.2 mm high


def test_the_weave_height_is_flat_where_its_truth_is(tmp_path):
    # the demo's weave (3 mm deep, 5 mm pitch), shadows, highlights and noise as the demo
    path = Path("examples/scenes/default.toml")
    data = tomllib.loads(path.read_text())
    data["render"] = {"scale": 0.5, "supersample": 1}
    scene = scene_from_dict(data, source=str(path), base_dir=path.parent)
    _, truth, _ = texel_truth_over_footprints(scene, SIZE)
    archive = _record(scene, tmp_path)
    run_stages(archive, [PsStage(size=SIZE)])
    height = _view(archive)["height_mm"]
    # measured: −3.34 mm deep at its deepest texel (the truth −3.00; 0.1 % of texels below
    # −2.87), 0.0032 mm of low-frequency error and of low-frequency shape (the truth's
    # 0.0032); before flat_beyond_mm: −4.49, 0.365, 0.362
    assert height.min() > truth.min() - 0.5, height.min()
    assert low_frequency_std(height - truth) < 0.01
    assert low_frequency_std(height) < 0.01


def test_a_frame_still_flagged_is_left_out_of_the_solve(plain):
    """A lamp's frame the session flagged as not recording its state (and could not take
    again) does not reach the solver: the view is solved from the other lamps."""
    from dataclasses import replace

    from processing.offline.runner import frame_camera, views_of
    from rig.archive import Archive, FrameFlag
    from rig.config import RigConfig

    archive, _ = plain
    with Archive.open(archive, mode="r") as arch:
        (view,) = views_of(arch, "ps")
        config = RigConfig.model_validate(arch.rig_config)
        records = {s.index: s for s in arch.step_table()}
        steps = [records[i] for i in view.steps]
        frames = [arch.read_frame(s.index, view.camera, 0) for s in steps]
        lens = frame_camera(arch, config, view.camera, view.turntable_deg)
    stage = PsStage(size=SIZE)
    whole = stage.solve(view, config, lens, steps, frames)
    wrong = FrameFlag(view.camera, 0, "lamps read back lit [], planned ['lamp3']", False)
    steps[2] = replace(steps[2], flags=(wrong,))
    solved = stage.solve(view, config, lens, steps, frames)
    assert whole["lamps"] == [s.lamp for s in steps]
    assert solved["lamps"] == [s.lamp for i, s in enumerate(steps) if i != 2]
    assert solved["valid"].mean() > 0.9  # the others still give the view


def test_rerun_replaces_and_a_failed_run_keeps_the_output(plain):
    archive, _ = plain
    run_stages(archive, [PsStage(size=32)])
    assert _view(archive)["normals"].shape == (32, 32, 3)

    class Broken(PsStage):
        def compute(self, archive_path, item):
            raise RuntimeError("a worker fell over")

    with pytest.raises(StageFailed, match=r"stage ps, view .*RuntimeError: a worker fell over"):
        run_stages(archive, [Broken(size=16)])
    assert _view(archive)["normals"].shape == (32, 32, 3)  # the previous output, whole


def test_robust_solver_beats_least_squares_with_cast_shadows(tmp_path):
    # the recess walls on the square's edge cast shadows over its border texels (the
    # example's 1.2 mm bumps hardly shadow each other under lamps at 45°)
    scene = _scene(["shadows"], margin_mm=0.0)
    with Simulator(scene) as sim:
        truth = sim.texel_truth(SIZE)
    archive = _record(scene, tmp_path)
    errors = {}
    for method in ("lsq", "irls"):
        run_stages(archive, [PsStage(size=SIZE, method=method)])
        got = _view(archive)
        errors[method] = _angular_error_deg(got["normals"], truth.normals)[got["valid"]].mean()
    assert errors["irls"] < 2.0 and errors["irls"] < errors["lsq"], errors


def test_cli_process_writes_previews_and_refuses_bad_input(plain, tmp_path):
    archive, _ = plain
    runner = CliRunner()
    result = runner.invoke(
        app, ["process", str(archive), "--size", "32", "--previews", str(tmp_path / "png")]
    )
    assert result.exit_code == 0, result.output
    assert len(list((tmp_path / "png").glob("*_normals.png"))) == 1
    bad = runner.invoke(app, ["process", str(archive), "--stages", "ps,nope"])
    assert bad.exit_code == 2 and "nope" in bad.output
    assert "valid are ['btf', 'mdf', 'pbr', 'ps']" in bad.output
