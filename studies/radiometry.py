"""`rig bench radiometry`: what the radiometric corrections buy, against the simulator's truth.

One simulated rig, three sessions through the daemon, all from the zenith camera:
the response calibration (an exposure bracket of the ChArUco wedge, Debevec &
Malik), the white target under every lamp (the flat fields), and a bumps sample
under a camera with a gamma-2.2 tone curve (``response``) and ``vignetting``,
lit by the rig's near lamps (their cos θ / r² fall-off over the sample). The
calibration file and its flat fields are the rig config's, so the daemon copies
them into the sample's archive; ``rig process`` then runs ``ps`` and ``btf``
with and without the corrections (``--raw``). It runs the simulator, the
calibration code and processing side by side, so it lives on top of them.
"""

from __future__ import annotations

import tempfile
import tomllib
from pathlib import Path

import numpy as np
from scipy import ndimage

from calibration import flat_fields
from calibration.plans import response_plan, white_plan
from calibration.sessions import calibrate_responses
from orchestrator.local import run_local
from processing.btf import reconstruct
from processing.offline import BtfStage, PsStage, run_stages
from rig.archive import Archive
from rig.calfile import CalibrationFile, Provenance, ResponseResult, write_calibration
from rig.clock import VirtualClock
from rig.material import FlatFieldMaps, read_btf, read_material, write_flat_field
from sim import Simulator
from sim.calibration import target_scene
from sim.rig import SimulatedRig
from sim.scene import scene_from_dict
from studies import EXAMPLE_SCENES

__all__ = ["FULL", "QUICK", "measure", "record", "run"]

_PLAN = """
[sample]
name = "radiometry"
[captures.ps]
views = [[0, 0]]
lights = {{theta_deg = 45, count = {ps_lights}}}
[captures.btf]
views = [[0, 0], [30, 0]]
lights = {{theta_deg = 45, count = {btf_lights}}}
[exposure]
exposure_s = 0.05
"""
#: the zenith camera (ps, btf at θ = 0, the white target) and the 30° one (btf)
_CAMERAS = ("cam0", "cam2")
_BUMPS = EXAMPLE_SCENES / "bumps.toml"


def run(quick: bool = False) -> list[dict]:
    """Rows: the sample with the effects, processed ``raw`` and ``corrected``, and the
    same sample without them (``no effects``: what the stages reach when the camera is
    linear and nothing vignettes). Columns: PS mean and 95th-percentile angular error
    (degrees), albedo non-uniformity (relative spread of measured over true albedo
    within one material) and contrast error (the checker's two materials), BTF
    relative RMSE against the ray-cast BTF (one scale fitted over all slots)."""
    setting = QUICK if quick else FULL
    with tempfile.TemporaryDirectory(prefix="rig-bench-radiometry-") as tmp:
        archive = record(Path(tmp), **setting)
        rows = [measure(archive, raw=raw, **setting) for raw in (True, False)]
        plain = record(Path(tmp) / "plain", effects=(), **setting)
        rows.append({**measure(plain, raw=True, effects=(), **setting), "mode": "no effects"})
    return rows


#: texels, image scale, lamps of the PS set and of the BTF's light set
FULL = {"size": 64, "scale": 0.5, "ps_lights": 12, "btf_lights": 6}
QUICK = {"size": 32, "scale": 0.5, "ps_lights": 8, "btf_lights": 4}
#: what the sample's camera and lamps do to its frames (the near lamps' fall-off is always there)
EFFECTS = ("response", "vignetting")


def record(
    workdir: Path, *, scale: float, ps_lights: int, btf_lights: int, effects=EFFECTS, **_
) -> Path:
    """The calibration sessions, the calibration file and the sample's archive in
    ``workdir``; the archive's path (its calibration is version 1)."""
    workdir.mkdir(parents=True, exist_ok=True)
    calibration = _calibrate(workdir, _sample_scene(scale, effects), scale)
    plan = _PLAN.format(ps_lights=ps_lights, btf_lights=btf_lights)
    update = {"calibration": str(calibration)}
    return _session(plan, _sample_scene(scale, effects), workdir / "sample.zarr", update)


def measure(
    archive: Path, *, raw: bool, size: int, scale: float, btf_lights: int, effects=EFFECTS, **_
) -> dict:
    """``ps`` and ``btf`` over ``archive`` (``raw``: without corrections), and their
    errors against the truth of the scene it was recorded from (one row)."""
    stages = [
        PsStage(size=size, raw=raw),
        BtfStage(size=size, components=btf_lights, raw=raw),  # full rank: no PCA error
    ]
    run_stages(archive, stages, workers=1)
    view = read_material(archive).frontal_ps()
    with Archive.open(archive) as recorded:
        btf = read_btf(recorded.material["btf"])
    with Simulator(_sample_scene(scale, effects)) as sim:
        return {
            "mode": "raw (--raw)" if raw else "corrected",
            "corrections": _applied(btf.radiometry),
            **_ps_errors(view, sim.texel_truth(size)),
            "btf_slots": int(btf.slot_valid.sum()),
            "btf_rel_rmse": _btf_error(btf, sim, size),
        }


def _sample_scene(scale: float, effects):
    data = tomllib.loads(_BUMPS.read_text())
    data["render"] = {"scale": scale, "supersample": 2}
    data["effects"] = list(effects)
    return scene_from_dict(data)


def _session(plan_text: str, scene, archive: Path, config_update: dict | None = None) -> Path:
    plan = archive.with_suffix(".plan.toml")
    plan.write_text(plan_text)
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as rig:
        config = rig.rig_config().model_copy(update=config_update or {})
        final = run_local(plan, config, archive=archive, clock=clock)
    if final["state"] != "done":
        raise RuntimeError(f"the simulated session {archive.name} ended {final['state']}")
    return archive


def _calibrate(workdir: Path, scene, scale: float) -> Path:
    """The calibration file with the response curve and the flat fields."""
    config = scene.rig
    response = {}
    for camera in _CAMERAS:
        bracket = workdir / f"response-{camera}.zarr"
        plan = response_plan(config, archive=str(bracket), camera=camera)
        _session(plan, target_scene("response", config, scale=scale, supersample=1), bracket)
        curves, exposures, failed = calibrate_responses(bracket)
        if camera not in curves:
            raise RuntimeError(f"no response curve for {camera}: {failed}")
        response[camera] = ResponseResult(curve=curves[camera].curve.tolist(), exposures=exposures)
    white, camera = workdir / "white.zarr", _CAMERAS[0]
    plan = white_plan(config, archive=str(white), camera=camera)
    _session(plan, target_scene("white", config, scale=scale, supersample=1), white)
    with Archive.open(white) as recorded:
        steps = recorded.step_table()
        frames = [recorded.read_frame(r.index, camera, 0) for r in steps]
    lamps = tuple(str(r.lamp) for r in steps)
    maps = FlatFieldMaps(camera, lamps, flat_fields(frames).falloff)
    path = workdir / "calibration.toml"
    write_flat_field(path.with_suffix(".flatfield.zarr"), maps)
    calibration = CalibrationFile(
        rig=config.name,
        response=response,
        response_provenance=Provenance.now(workdir / "response-*.zarr"),
        lamps_flat_field=path.with_suffix(".flatfield.zarr").name,
        lamps_provenance=Provenance.now(white),
    )
    return write_calibration(calibration, path)


def _applied(radiometry) -> str:
    parts = []
    if radiometry.linearised:
        parts.append("response")
    if radiometry.flat_fielded:
        parts.append(f"flat field ({len(radiometry.flat_fielded)} lamps)")
    return " + ".join(parts) or "none"


def _ps_errors(view, truth) -> dict:
    """Angular error; albedo over the truth within one material (its spread: how
    uniform) and the measured contrast of the checker's two materials against the
    true one (0.8 / 0.5: how linear)."""
    valid = view.valid
    cos = np.clip(np.sum(view.normals * truth.normals, axis=-1), -1.0, 1.0)
    err = np.degrees(np.arccos(cos))[valid]
    inner = np.zeros_like(valid)
    inner[2:-2, 2:-2] = True  # the recess border ring averages the holder in
    grey = truth.albedo.mean(axis=-1)
    measured = view.albedo.mean(axis=-1)
    # away from the checker's edges, where a texel averages both materials
    bright = ndimage.binary_erosion(grey > 0.7, iterations=2) & valid & inner
    dark = ndimage.binary_erosion(grey < 0.6, iterations=2) & valid & inner
    ratio = measured[bright] / grey[bright]
    contrast = np.median(measured[bright]) / np.median(measured[dark])
    true_contrast = np.median(grey[bright]) / np.median(grey[dark])
    return {
        "ps_mean_deg": float(err.mean()),
        "ps_p95_deg": float(np.percentile(err, 95)),
        "albedo_spread": float(np.std(ratio) / np.mean(ratio)),
        "albedo_contrast_err": float(contrast / true_contrast - 1.0),
    }


def _btf_error(btf, sim, size: int) -> float:
    """RMSE over the mean of the ray-cast BTF, of every measured (slot, light), after
    one least-squares scale (the lamps' power and exposure are not known)."""
    model = btf.model
    measured, true = [], []
    for j, view in enumerate(model.view_dirs_deg):
        if not btf.slot_valid[j]:
            continue
        for i, light in enumerate(model.light_dirs_deg):
            measured.append(reconstruct(model, view=j, light=i).astype(np.float64))
            true.append(sim.btf_truth(tuple(view), tuple(light), size).astype(np.float64))
    m, t = np.stack(measured), np.stack(true)
    scale = float(np.sum(m * t) / np.sum(m * m))  # the unknown lamp power and exposure
    return float(np.sqrt(np.mean((scale * m - t) ** 2)) / np.mean(t))
