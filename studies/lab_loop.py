"""``rig bench lab-loop``: the render loop as a lab runs it, on a rig not built to its config.

:mod:`studies.render_loop` measures on a simulated rig built exactly as its
config says, so processing with the config's nominal lamps is processing with
the truth. A lab's rig stands a few millimetres and a few percent off its
config. Here the simulated rig does too (the scene's ``[as_built]`` table,
:mod:`sim.as_built`: each lamp moved and made brighter or dimmer by seeded
amounts), while the rig config the daemon, the archive and processing see stays
the nominal one. Then, as a lab would:

1. **Calibrate the lamps** on that rig: the mirror-sphere and white-target
   sessions of ``rig calibrate lamps --sim`` (``calibration.plans``,
   ``sim.calibration.target_scene``, ``calibration.sessions.calibrate_lamps``),
   through the daemon in virtual time;
2. **measure** the render loop's BTF plan on the same rig
   (:func:`studies.render_loop.record`);
3. **process** it four ways: with the nominal config only (the archive holds
   no calibration), with the lamp calibration stored in the archive as
   ``rig calibrate lamps --apply`` stores it, that with each texel's light moved
   from its own direction to the calibrated lamp by the fitted PBR model
   (``lights="model"``), and, for reference, the same plan on a rig built exactly
   to its config;
4. **score** each as the render loop does (:func:`studies.render_loop.scores`:
   at the captured pairs nearest the held-out ones and at the held-out pairs,
   against the footprint truth).

Processing is never handed the simulator's as-built parameters; they are read
only to score the calibration (the lamp rows). It runs the simulator, the
calibration code and processing side by side, so it lives on top of them.
"""

from __future__ import annotations

import contextlib
import tempfile
from pathlib import Path

import numpy as np

from calibration.plans import lamp_plan, white_plan
from calibration.sessions import apply_calibration, calibrate_lamps
from processing.offline.texel_light import lamp_positions, plane_irradiance
from rig.calfile import (
    CalibrationFile,
    LampResult,
    Provenance,
    load_calibration,
    write_calibration,
)
from rig.config import RigConfig
from rig.errors import RigError
from rig.kinds import rig_kind
from rig.material import write_flat_field
from rig.plan import parse_plan
from sim.calibration import target_scene
from sim.scene import scene_from_dict
from sim.simulator import Simulator
from studies.render_loop import (
    HELD_OUT,
    PLANS,
    SCENES,
    irradiance_scale,
    loop_truth,
    plan_toml,
    process,
    record,
    scores,
)

__all__ = ["AS_BUILT", "PROCESSING", "calibrate", "lamp_errors", "run"]

#: The rig as built: each lamp up to ±5 mm off its place along each axis and
#: ±5 % off its intensity (uniform draws from the seed).
AS_BUILT = {"seed": 7, "lamp_position_mm": 5.0, "lamp_intensity": 0.05}

#: How each material was processed: the config's lamps; the calibrated lamps; the
#: calibrated lamps with each texel's light moved from its own direction by the fitted
#: PBR model (``BtfStage(lights="model")``); on a rig built exactly to its config.
PROCESSING = ("nominal", "calibrated", "calibrated, lights by model", "exact rig")

#: The per-view PCA components scored beside the lossless model.
COMPONENTS = 4

#: The cameras that see the mirror sphere (``rig calibrate lamps --sim``: every
#: camera; three keep the rendering to minutes) and the targets' supersampling
#: (the CLI's 4 × 4: the ball's outline and highlight).
LAMP_CAMERAS = ("cam0", "cam2", "cam4")
SUPERSAMPLE = 4


def run(
    quick: bool = False, *, scenes: tuple[str, ...] = tuple(SCENES),
    plans: tuple[str, ...] | None = None, as_built: dict | None = None,
) -> list[dict]:  # fmt: skip
    """``quick``: the bumps at 32² texels on the coarse plan, the sphere seen by two
    cameras; else both samples at 64² on the coarse and medium plans. ``plans``: which
    of the render loop's (:data:`~studies.render_loop.PLANS`); ``as_built``: the rig's
    ``[as_built]`` table (default :data:`AS_BUILT`).

    Rows, first one per calibrated lamp: ``lamp``, ``position_error_mm`` (calibrated
    against where the lamp stands as built; ``nominal_error_mm``: the config's),
    ``intensity_error_pct`` (relative intensities, each set over its mean) and
    ``irradiance_error_pct`` (what processing divides by: the irradiance the lamp
    gives the sample's centre, from the calibration over the as-built one, each
    over its mean; ``nominal_irradiance_error_pct``: the config's). Then one per
    (scene, plan, processing, c): ``processing`` (:data:`PROCESSING`),
    ``components`` (c, or ``lossless``), ``psnr_captured_db``,
    ``psnr_held_out_db`` (as :func:`studies.render_loop.scores`), ``truth_rays``
    (the footprint truth's rays per texel side), ``slots`` (view slots registered).
    """
    as_built = dict(AS_BUILT if as_built is None else as_built)
    scenes = ("bumps",) if quick and scenes == tuple(SCENES) else scenes
    plans = plans if plans is not None else (("coarse",) if quick else ("coarse", "medium"))
    unknown = [s for s in scenes if s not in SCENES] + [p for p in plans if p not in PLANS]
    if unknown:
        raise RigError(
            f"unknown scene or plan {unknown}; valid scenes {list(SCENES)}, plans {list(PLANS)}"
        )
    size = 32 if quick else 64
    cameras = LAMP_CAMERAS[:2] if quick else LAMP_CAMERAS
    config = RigConfig()  # the render loop's scenes stand on the default rig
    with tempfile.TemporaryDirectory(prefix="rig-bench-lab-loop-") as tmp:
        workdir = Path(tmp)
        calibration = calibrate(workdir / "calibrations", config, as_built, cameras=cameras)
        # the draw depends on the rig and the table alone: any sample's scene holds it
        rows = lamp_errors(calibration, scene_from_dict(_scene("bumps", as_built)))
        for name in scenes:
            for plan in plans:
                rows += _sample_rows(workdir / f"{name}-{plan}", name, plan, as_built,
                                     calibration, size)  # fmt: skip
    return rows


def _scene(name: str, as_built: dict | None) -> dict:
    """The render loop's scene ``name``, on the rig as built (None: exactly to its config)."""
    return SCENES[name] | ({"as_built": as_built} if as_built is not None else {})


def calibrate(
    folder: Path, config: RigConfig, as_built: dict, *, cameras=LAMP_CAMERAS,
    supersample: int = SUPERSAMPLE, scale: float = 0.5,
) -> Path:  # fmt: skip
    """``rig calibrate lamps --sim`` on the rig ``config`` as built: the mirror sphere
    seen by ``cameras``, the white target by the zenith camera, each a session through
    the daemon; the calibration file (lamps and their flat fields) written in ``folder``."""
    sphere, white = folder / "lamps", folder / "lamps-white"
    for path in (sphere, white):
        path.mkdir(parents=True)
    sessions = {}
    for target, path, plan in (
        ("lamps", sphere, lamp_plan(config, archive="lamps.zarr", cameras=cameras)),
        ("white", white, white_plan(config, archive="lamps-white.zarr")),
    ):
        scene = target_scene(target, config, scale=scale, supersample=supersample,
                             as_built=as_built)  # fmt: skip
        sessions[target], _ = record(scene, plan, path)
    results, lamp_run, failed = calibrate_lamps(sessions["lamps"], sessions["white"])
    if failed or lamp_run.flat_field is None:
        raise RigError(f"the lamp calibration of the simulated rig failed: {failed}")
    path = folder / "calibration.toml"
    maps = write_flat_field(path.with_suffix(".flatfield.zarr"), lamp_run.flat_field)
    calibration = CalibrationFile(
        rig=config.name, lamps=results, lamps_provenance=Provenance.now(sessions["lamps"]),
        lamps_flat_field=maps.name,
    )  # fmt: skip
    return write_calibration(calibration, path)


def lamp_errors(calibration_path: Path, scene) -> list[dict]:
    """The calibrated lamps against where and how bright the simulated rig's lamps
    are as built (``scene.as_built``: the simulator's truth, read only here)."""
    calibration = load_calibration(calibration_path)
    config, truth = scene.rig, scene.as_built
    kind = rig_kind(config)
    lamps: dict[str, LampResult] = {k: v for k, v in calibration.lamps.items()
                                    if v.position_mm is not None}  # fmt: skip
    nominal = {k: kind.recorded_lamp_mm(config, k, {}) for k in lamps}
    built = {k: nominal[k] + truth.lamp_offset_mm[k] for k in lamps}
    gains = lamp_positions(config, calibration).centre_gain
    # the irradiance each lamp gives the sample's centre as built, over the config's
    true = {k: float(truth.lamp_gain[k] * plane_irradiance(built[k], np.zeros(3))
                  / plane_irradiance(nominal[k], np.zeros(3))) for k in lamps}  # fmt: skip
    mean_true = float(np.mean(list(true.values())))
    intensity = {k: lamps[k].intensity or 1.0 for k in lamps}
    mean_intensity = float(np.mean(list(intensity.values())))
    mean_gain = float(np.mean([truth.lamp_gain[k] for k in lamps]))
    rows = []
    for k in lamps:
        rows.append({
            "lamp": k,
            "position_error_mm": round(_distance(lamps[k].position_mm, built[k]), 2),
            "nominal_error_mm": round(_distance(nominal[k], built[k]), 2),
            "intensity_error_pct": round(100 * ((intensity[k] / mean_intensity)
                                                / (truth.lamp_gain[k] / mean_gain) - 1), 2),
            "irradiance_error_pct": round(100 * (gains[k] / (true[k] / mean_true) - 1), 2),
            "nominal_irradiance_error_pct": round(100 * (mean_true / true[k] - 1), 2),
        })  # fmt: skip
    return rows


def _distance(a, b) -> float:
    return float(np.linalg.norm(np.subtract(a, b)))


def _sample_rows(folder: Path, name: str, plan: str, as_built: dict, calibration: Path,
                 size: int) -> list[dict]:  # fmt: skip
    """The plan on the rig as built (processed nominal, then calibrated) and on the rig
    built exactly to its config; their scores against one footprint truth."""
    lights = len(parse_plan(plan_toml(plan)).captures.btf.lights.resolve().directions)
    materials, scale = {}, None
    for built, label in ((as_built, "nominal"), (None, "exact rig")):
        scene = scene_from_dict(_scene(name, built))
        session = folder / label.replace(" ", "-")
        session.mkdir(parents=True)
        archive, config = record(scene, plan_toml(plan), session)
        if config.calibration is not None:
            raise RigError(f"the loop's rig config names a calibration: {config.calibration}")
        scale = irradiance_scale(scene, config)  # the config's lamps: the same for both
        # as many components as lights: the per-view PCA is then lossless
        materials[label] = process(archive, size=size, components=lights)
        if built is not None:
            apply_calibration(load_calibration(calibration), calibration, archive)
            materials["calibrated"] = process(archive, size=size, components=lights)
            materials["calibrated, lights by model"] = process(
                archive, size=size, components=lights, lights="model"
            )
    with contextlib.closing(Simulator(scene_from_dict(SCENES[name]))) as sim:
        # the most demanding score converges the truth: the rig built to its config
        truth = loop_truth(materials["exact rig"], sim, scale, HELD_OUT, components=lights)
    rows = []
    for label in PROCESSING:
        material = materials[label]
        for c, column in ((COMPONENTS, COMPONENTS), (lights, "lossless")):
            held = scores(material, truth, scale, HELD_OUT, c=c)
            rows.append({
                "scene": name, "plan": plan, "processing": label, "components": column,
                "psnr_captured_db": held["psnr_captured_db"],
                "psnr_held_out_db": held["psnr_cpu_db"],
                "truth_rays": max(truth.held_out.rays, truth.captured.rays),
                "slots": int(np.sum(material.btf_slot_valid)),
            })  # fmt: skip
    return rows
