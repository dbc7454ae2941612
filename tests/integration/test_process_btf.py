"""`rig process --stages btf` on a session recorded against the simulated rig: every measured
(view slot, light) comes back from the material's per-view PCA as the registered frame,
and from a UBO2003 export within 8-bit quantisation."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from orchestrator.cli import app
from orchestrator.local import run_local
from processing.btf import reconstruct, view_slots
from processing.offline import BtfStage, run_stages
from processing.registration import register_capture
from rig.archive import Archive
from rig.clock import VirtualClock
from rig.config import RigConfig
from rig.geometry import texel_centers_mm
from rig.interchange import read_image, srgb_decode, ubo2003_file, ubo2003_view_folder
from rig.kinematics import lamp_position_mm
from rig.material import btf_from_arrays
from sim.rig import SimulatedRig
from sim.scene import scene_from_dict
from sim.shading import LightSource

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow

SIZE = 32
PLAN = """
[sample]
name = "btf"
[captures.btf]
views = [[0, 0], [30, 0], [30, 90]]
lights = {theta_deg = 45, count = 6}
[exposure]
exposure_s = 0.05
"""


def _record(tmp, scale, plan=PLAN):
    data = tomllib.loads(Path("examples/scenes/bumps.toml").read_text())
    data["render"] = {"scale": scale, "supersample": 2}
    (tmp / "plan.toml").write_text(plan)
    clock = VirtualClock()
    with SimulatedRig(scene_from_dict(data), clock=clock) as sim:
        final = run_local(tmp / "plan.toml", sim.rig_config(), archive=tmp / "b.zarr", clock=clock)
    assert final["state"] == "done", final
    return tmp / "b.zarr"


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    return _record(tmp_path_factory.mktemp("btf"), 0.5)


def _material(path):
    with Archive.open(path) as arch:
        group = arch.material["btf"]
        arrays = {k: group[k][:] for k in group.array_keys()}
        return arrays, dict(group.attrs)


def _registered(path, slot, light):
    with Archive.open(path) as arch:
        config = RigConfig.model_validate(arch.rig_config)
        table = view_slots(arch.step_table())
        step, camera = int(table.steps[slot, light]), str(table.cameras[slot, light])
        record = next(s for s in arch.step_table() if s.index == step)
        frame = arch.read_frame(step, camera, 0)
    reg = register_capture(frame, config, record, camera, size=SIZE).registration
    full_scale = 2 ** config.camera(camera).bit_depth - 1
    return reg.normtexture.texture / (full_scale * record.exposures_s[0])


def test_full_rank_pca_gives_back_every_registered_frame(archive):
    # raw: the registered frames as recorded (the near-lamp irradiance is tested below)
    (run,) = run_stages(archive, [BtfStage(size=SIZE, components=6, raw=True)])
    assert run.summary == {"slots": 3, "flagged_frames": 0, "displaced_pairs": 0, "components": 6}
    arrays, attrs = _material(archive)
    assert arrays["slot_valid"].all() and attrs["flagged"] == []
    model = btf_from_arrays(arrays, attrs)
    for slot in range(3):
        for light in range(6):
            want = _registered(archive, slot, light)
            got = reconstruct(model, view=slot, light=light)
            # float16 bases: ~1e-3 relative
            assert np.abs(got - want).max() <= 2e-3 * np.abs(want).max() + 1e-4


def test_fewer_components_cost_accuracy_not_validity(archive):
    errors = []
    for c in (1, 3):
        run_stages(archive, [BtfStage(size=SIZE, components=c, raw=True)])
        model = btf_from_arrays(*_material(archive))
        want = _registered(archive, 1, 2)
        errors.append(np.sqrt(np.mean((reconstruct(model, view=1, light=2) - want) ** 2)))
    assert errors[0] > errors[1] > 0


def _simulated_irradiance(path, slot, light):
    """(SIZE, SIZE) E cos θ on the plane, texel over centre, of the capture's lamp (the
    simulator's lamp model)."""
    with Archive.open(path) as arch:
        config = RigConfig.model_validate(arch.rig_config)
        table = view_slots(arch.step_table())
        step = int(table.steps[slot, light])
        record = next(s for s in arch.step_table() if s.index == step)
    position = lamp_position_mm(config, record.lamp, arc_deg=record.actuators["arc_deg"],
                                turntable_deg=record.actuators["turntable_deg"])  # fmt: skip
    xy = texel_centers_mm(config.holder.sample_mm, SIZE).reshape(-1, 2)
    points = np.vstack([np.column_stack([xy, np.zeros(len(xy))]), [[0.0, 0.0, 0.0]]])
    dirs, e = LightSource(position, "point", 1.0).incident(points)
    e = e * dirs[:, 2]
    return (e[:-1] / e[-1]).reshape(SIZE, SIZE)


def test_each_texel_is_divided_by_its_near_lamp_irradiance_and_the_material_says_so(archive):
    # each texel at its capture's own light: the irradiance alone is divided out
    run_stages(archive, [BtfStage(size=SIZE, components=6, lights="nominal")])
    arrays, attrs = _material(archive)
    model = btf_from_arrays(arrays, attrs)
    radiometry = json.dumps(attrs)
    assert "the rig config's lamp geometry (nominal)" in radiometry
    assert "near-lamp irradiance per texel divided out" in radiometry
    for slot, light in ((0, 0), (2, 4)):
        want = _registered(archive, slot, light) / _simulated_irradiance(archive, slot, light)[
            ..., None]  # fmt: skip
        got = reconstruct(model, view=slot, light=light)
        assert np.abs(got - want).max() <= 2e-3 * np.abs(want).max() + 1e-4
    run_stages(archive, [BtfStage(size=SIZE, components=6, raw=True)])
    assert "irradiance" in json.dumps(_material(archive)[1])  # skipped, and why


def test_frames_whose_markers_are_too_small_are_flagged_never_warped(tmp_path):
    # At 0.155 of the rig's resolution the 30° views' markers are a few pixels wide, their
    # modules under a pixel across the foreshortened axis: neither tracked from the rig's
    # pose nor detected. The frontal view's are still tracked (at a quarter of the resolution
    # every view's are; at an eighth none are).
    small = _record(tmp_path, 0.155)
    (run,) = run_stages(small, [BtfStage(size=SIZE, components=4)])
    arrays, attrs = _material(small)
    flagged_slots = {f[0] for f in attrs["flagged"]}
    assert run.summary["flagged_frames"] == len(attrs["flagged"]) > 0
    assert all(f[4] in ("TOO_FEW_MARKERS", "COLLINEAR_MARKERS", "HIGH_REPROJECTION",
                        "ILL_CONDITIONED") for f in attrs["flagged"])  # fmt: skip
    for slot in range(3):
        assert arrays["slot_valid"][slot] == (slot not in flagged_slots)
        if slot in flagged_slots:  # stored empty, not filled with a bad warp
            assert not arrays["mean"][slot].any() and arrays["rank"][slot] == 0
    assert arrays["slot_valid"].any()  # the frontal view registers


def test_the_ubo2003_export_holds_the_registered_frames(archive, tmp_path):
    out = tmp_path / "ubo"
    args = ["export", "ubo2003", str(archive), "--out", str(out), "--size", str(SIZE)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    manifest = json.loads((out / "manifest.json").read_text())
    white, lights = manifest["white"], manifest["lights_deg"]
    assert manifest["gaps"] == [] and len(manifest["views_deg"]) == 3 and len(lights) == 6
    for slot, view in enumerate(manifest["views_deg"]):
        for light in (0, 3):
            path = out / ubo2003_view_folder(view) / ubo2003_file(light, lights[light], view)
            got = white * srgb_decode(read_image(path) / 255.0)
            want = _registered(archive, slot, light)
            below = want < white  # the brightest 0.1 % of the frontal slot clip at 255
            assert below.mean() > 0.99
            # half an 8-bit code of sRGB is at most 0.0045 of white in linear terms
            assert np.abs(got - want)[below].max() <= 0.0045 * white


def test_per_texel_views_are_resampled_and_recorded(archive):
    run_stages(archive, [BtfStage(size=SIZE, components=6, views="per texel")])
    arrays, attrs = _material(archive)
    radiometry = json.loads(json.dumps(attrs["radiometry"]))
    assert radiometry["sources"]["view"] == "the rig config's camera geometry (nominal)"
    assert "outside the hull" in radiometry["skipped"]["view"]
    resampled = btf_from_arrays(arrays, attrs)
    run_stages(archive, [BtfStage(size=SIZE, components=6)])
    nominal = btf_from_arrays(*_material(archive))
    assert "views 'nominal'" in json.dumps(_material(archive)[1])
    for slot in range(3):
        got = reconstruct(resampled, view=slot, light=2)
        want = reconstruct(nominal, view=slot, light=2)
        assert np.isfinite(got).all()
        # a few degrees' turn: the texels move, by a few percent at most
        assert 0 < np.abs(got - want).max() <= 0.1 * np.abs(want).max()


def test_per_texel_lights_are_resampled_and_recorded_with_per_texel_views(archive):
    """The lamps 650 mm away, placed from the rig config: each texel's captures moved onto
    the plan's lights, a few percent, and on the hull's rim some kept and counted; with
    per-texel views too, both are recorded; they are the stage's default."""
    run_stages(archive, [BtfStage(size=SIZE, components=6, lights="nominal")])
    nominal = btf_from_arrays(*_material(archive))
    run_stages(archive, [BtfStage(size=SIZE, components=6)])
    arrays, attrs = _material(archive)
    radiometry = json.loads(json.dumps(attrs["radiometry"]))
    assert radiometry["sources"]["light"] == radiometry["sources"]["irradiance"]
    assert "nominal" in radiometry["sources"]["light"]
    kept = radiometry["skipped"]["light"]
    count, total = (int(x) for x in kept.split(" texel captures")[0].split(" of "))
    assert 0 < count < total == 3 * 6 * SIZE * SIZE  # the 45° ring: the hull's rim
    resampled = btf_from_arrays(arrays, attrs)
    for slot in range(3):
        got = reconstruct(resampled, view=slot, light=2)
        want = reconstruct(nominal, view=slot, light=2)
        assert np.isfinite(got).all()
        assert 0 < np.abs(got - want).max() <= 0.1 * np.abs(want).max()
    run_stages(archive, [BtfStage(size=SIZE, components=6, lights="per texel",
                                  views="per texel")])  # fmt: skip
    both = json.loads(json.dumps(_material(archive)[1]["radiometry"]))
    assert {"light", "view"} <= both["sources"].keys()
    assert both["skipped"]["light"] == kept  # lights first, per slot: the same captures kept
    run_stages(archive, [BtfStage(size=SIZE, components=6, lights="per texel", raw=True)])
    raw = json.loads(json.dumps(_material(archive)[1]["radiometry"]))
    assert "light" not in raw["sources"] and raw["skipped"]["light"].startswith("--raw")


def test_saturated_texels_are_counted_in_the_material(archive, tmp_path):
    # 20 × the exposure: the frontal view's brightest texels clip
    bright = _record(tmp_path, 0.5, PLAN.replace("exposure_s = 0.05", "exposure_s = 1.0"))
    run_stages(bright, [BtfStage(size=SIZE, components=4)])
    arrays, attrs = _material(bright)
    skipped = attrs["radiometry"]["skipped"]
    count = int(skipped["saturated"].split()[0])
    assert 0 < count <= 3 * 6 * SIZE * SIZE
    model = btf_from_arrays(arrays, attrs)
    assert np.isfinite(reconstruct(model, view=0, light=0)).all()
    run_stages(archive, [BtfStage(size=SIZE, components=4)])  # the usual exposure: none
    assert "saturated" not in _material(archive)[1]["radiometry"]["skipped"]
