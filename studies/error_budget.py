"""``rig bench error-budget``: the render loop's error, term by term.

The loop of :mod:`studies.render_loop` (a simulated sample measured
through the daemon, processed by the ``btf`` stage, interpolated at held-out
directions) is run with the simulator's error terms switched off one at a time
and all together. A term is switched off in the *scene*, never in processing:

- ``noise``: the scene does not list the ``noise`` effect (no photon, read or
  quantisation noise beyond the 8/16-bit DN);
- ``near lamps``: the rig's lamps are ``directional`` (at infinity, each giving
  the irradiance a point lamp at its position gives at the turntable centre)
  instead of ``point`` lamps at the light arc's radius;
- ``point pixels``: each pixel shades 3 × 3 points and averages them
  (``render.supersample``), as a sensor integrates over its pixel's area,
  instead of its centre alone;
- ``perspective``: the cameras stand :data:`TELECENTRIC_FACTOR` × farther with
  as much longer a lens (the rig config says so too): the same pixels on the
  sample, seen along nearly parallel rays, as an ideal orthographic camera.

Two terms are registration's: the frames stay the same, and registration is
handed what the simulator knows exactly (:data:`REGISTRATION_TERMS`):

- ``marker registration``: each frame is registered from its camera's true
  pose (the rig config's, where the simulator puts the camera) instead of from
  the markers it detects;
- ``box filter``: frames are resampled onto the texels with pixel-area weights
  (``processing.registration.rectify``'s ``"area"`` filter) instead of the box
  of bilinear samples.

Three more terms are processing's own choices, read from every run: the
per-texel near-lamp irradiance (each session processed as it is, and
``raw``: without it, :mod:`processing.offline.texel_light`; more ways in
:data:`PROCESSINGS`, e.g. each texel's own light directions resampled onto the
plan's), compression (the
per-view PCA at c against all its components, lossless) and interpolation
(the material at held-out directions against the captured pairs nearest
them). Everything is scored against the footprint truth
(:func:`studies.footprint.converged_truth`, converged on the run with all
terms off, the most demanding score) with the peak of the held-out truth.

Beside each score at the captured pairs stands the floor the sensor model implies
there (:mod:`studies.noise_floor`): the score if the sensor's noise were the
loop's only error, derived from the noise model, the registration's footprint
and the compression, not measured.
"""

from __future__ import annotations

import contextlib
import itertools
import tempfile
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from processing.btf import psnr_db, rmse
from rig.config import RigConfig
from rig.errors import RigError
from rig.plan import parse_plan
from sim.scene import scene_from_dict
from sim.simulator import Simulator
from studies.footprint import truth_at
from studies.noise_floor import capture_gains, floor_db, leverage
from studies.render_loop import (
    HELD_OUT,
    PLANS,
    SCENES,
    captured_pairs,
    interpolated,
    irradiance_scale,
    loop_truth,
    plan_toml,
    process,
    reconstructed,
    record,
    truncated,
)

__all__ = [
    "CONFIGS",
    "MAX_RENDER_SCALE",
    "PROCESSINGS",
    "REGISTRATION_TERMS",
    "TERMS",
    "components_of",
    "plot",
    "run",
    "scene_without",
]

#: The simulator's error terms, each as the scene change that switches it off.
TERMS: dict[str, str] = {
    "noise": "the scene does not list the noise effect",
    "near lamps": "directional lamps (at infinity) instead of point lamps 650 mm away",
    "point pixels": "3 × 3 shaded points per pixel instead of the pixel centre",
    "perspective": "cameras 50 × farther with 50 × the focal length (telecentric) "
    "instead of pinholes 800 mm away",
    "marker registration": "registered from the cameras' true pose instead of the markers",
    "box filter": "pixel-area resampling weights instead of a box of bilinear samples",
}

#: The terms that are registration's, not the scene's: each switched off by the
#: btf stage option that hands registration what the simulator knows exactly
#: (the pose the scene's rig config gives the cameras) or resamples without the
#: bilinear tent. The frames are the same.
REGISTRATION_TERMS: dict[str, dict] = {
    "marker registration": {"from_pose": True},
    "box filter": {"filter": "area"},
}

#: How much farther, with how much longer a lens, the cameras stand when
#: ``perspective`` is off: the view turns by ±0.07° across the sample, not ±3.6°.
TELECENTRIC_FACTOR = 50.0

#: The largest ``render_scale`` (frames at this multiple of the camera's resolution).
MAX_RENDER_SCALE = 4.0

#: Shaded points per pixel side when ``point pixels`` is off.
PIXEL_SUPERSAMPLE = 3

#: The runs: which terms are off, all on first and all off last.
CONFIGS: tuple[tuple[str, ...], ...] = ((), *((term,) for term in TERMS), tuple(TERMS))

#: How each session can be processed: label → the btf stage's options. ``run`` takes
#: the first two unless asked.
PROCESSINGS: dict[str, dict] = {
    "raw": {"raw": True},
    "irradiance per texel": {"lights": "nominal"},
    "lights per texel": {"lights": "per texel"},
    "lights and views per texel": {"lights": "per texel", "views": "per texel"},
    "lights by model": {"lights": "model"},
    "lights and views by model": {"lights": "model", "views": "model"},
}

#: The per-view PCA components scored beside the lossless model.
COMPONENTS = 4


def scene_without(name: str, off: tuple[str, ...], *, render_scale: float | None = None) -> dict:
    """The scene dict of ``SCENES[name]`` with the terms in ``off`` switched off, its
    frames rendered at ``render_scale`` of the camera's resolution (None: the scene's)."""
    unknown = [term for term in off if term not in TERMS]
    if unknown:
        raise RigError(f"unknown error terms {unknown}; valid terms {list(TERMS)}")
    off = tuple(term for term in off if term not in REGISTRATION_TERMS)
    spec = dict(SCENES[name])
    if render_scale is not None:
        spec["render"] = spec["render"] | {"scale": render_scale}
    if "noise" in off:
        spec["effects"] = [e for e in spec["effects"] if e != "noise"]
    overrides = {}
    if "near lamps" in off:
        lamps = [lamp.model_dump() | {"kind": "directional"}
                 for lamp in RigConfig().light_arc.lamps]  # fmt: skip
        overrides["light_arc"] = {"lamps": lamps}
    if "perspective" in off:  # the same pixels on the sample, from (nearly) parallel rays
        arc, k = RigConfig().camera_arc, TELECENTRIC_FACTOR
        cameras = [cam.model_dump() | {"fx_px": cam.fx_px * k, "fy_px": cam.fy_px * k}
                   for cam in arc.cameras]  # fmt: skip
        overrides["camera_arc"] = {"radius_mm": arc.radius_mm * k, "cameras": cameras}
    if overrides:
        spec["rig"] = {"overrides": overrides}
    if "point pixels" in off:
        spec["render"] = spec["render"] | {"supersample": PIXEL_SUPERSAMPLE}
    return spec


def components_of(btf) -> int:
    """Every component the per-view PCA stored (basis: (views, c, N, N, C)): lossless."""
    return btf.basis.shape[1]


def _label(off: tuple[str, ...]) -> str:
    if not off:
        return "all terms on"
    return "all terms off" if set(off) == set(TERMS) else f"{' + '.join(off)} off"


def _scores(material, scale, truths, components: int, sensor: dict) -> dict:
    """PSNRs at the captured pairs and the held-out ones of one material at c, and the
    floor the sensor's noise sets at the captured pairs (``sensor``: :func:`_sensor`)."""
    btf, valid = material.btf, np.asarray(material.btf_slot_valid, bool)
    captured = captured_pairs(btf, valid, HELD_OUT)
    model = truncated(btf, components)
    kept = leverage(model, captured, components)
    held = interpolated(model, valid, HELD_OUT) / scale
    at_captured = reconstructed(model, captured) / scale
    own, truth_captured = truths
    peak = float(own.max())
    return {
        "psnr_captured_db": round(psnr_db(rmse(at_captured, truth_captured), peak=peak), 2),
        "noise_floor_captured_db": round(
            floor_db(truth_captured, scale=scale, peak=peak, kept=kept, **sensor), 2
        ),
        "psnr_held_out_db": round(psnr_db(rmse(held, own), peak=peak), 2),
        "scale_fit_captured": round(_fit_ratio(at_captured, truth_captured), 4),
        "scale_fit_held_out": round(_fit_ratio(held, own), 4),
    }


def _fit_ratio(measured: np.ndarray, truth: np.ndarray) -> float:
    """The least-squares scale of ``measured`` onto ``truth``, as its inverse: the
    factor by which ``measured`` (already divided by the derived scale) is too bright."""
    return float(np.sum(measured * measured) / np.sum(measured * truth))


def _converged(material, sim, scale, most: int):
    """Footprint truths at the held-out and captured pairs, their rays per texel side
    (at most ``most``) and the larger change of the two scores at the last doubling (dB)."""
    btf = material.btf
    truth = loop_truth(material, sim, scale, HELD_OUT, components=components_of(btf), most=most)
    own, at = truth.held_out, truth.captured
    dirs = [(btf.view_dirs_deg[j], btf.light_dirs_deg[i]) for j, i in truth.pairs]
    rays = max(own.rays, at.rays)

    def at_rays(result, pairs):
        return result.values if result.rays == rays else truth_at(sim, pairs, material.size, rays)

    change = round(max(own.change_db, at.change_db), 3)
    return at_rays(own, HELD_OUT), at_rays(at, dirs), rays, change


def run(
    quick: bool = False, *, scenes: tuple[str, ...] = tuple(SCENES),
    plans: tuple[str, ...] | None = None, runs: tuple[tuple[str, ...], ...] = CONFIGS,
    processings: tuple[str, ...] = ("raw", "irradiance per texel"),
    render_scale: float | None = None, truth_rays: int = 32,
) -> list[dict]:  # fmt: skip
    """``quick``: 32² texels, the coarse plan; else 64² texels, the coarse and
    medium plans. ``scenes``, ``plans``: which of the render loop's to run;
    ``runs``: which terms are off in each run (default :data:`CONFIGS`; the run
    with the most terms off converges the truth); ``processings``: which of
    :data:`PROCESSINGS` each session goes through; ``render_scale``: the frames'
    resolution as a fraction of the camera's (None: the loop's scenes', 0.5);
    ``truth_rays``: the most rays per texel side the truth may double to.

    Rows, one per (scene, plan, run, processing, c): ``scene``, ``plan``, ``run``
    (which terms are off), ``off`` (their names), ``processing`` (``raw``, or the
    near-lamp ``irradiance per texel`` divided out, or another of
    :data:`PROCESSINGS`), ``components`` (c, or every component:
    ``lossless``), ``psnr_captured_db`` (the material at the captured pairs
    nearest the held-out ones against the truth there), ``noise_floor_captured_db``
    (what that score would be if the sensor's noise were the only error: derived
    from the sensor model, :mod:`studies.noise_floor`), ``psnr_held_out_db``
    (interpolated at :data:`~studies.render_loop.HELD_OUT`),
    ``scale_fit_captured`` / ``scale_fit_held_out`` (the least-squares scale over
    the derived one, :func:`~studies.render_loop.irradiance_scale`, at the
    captured and the held-out pairs), ``truth_rays`` / ``truth_change_db`` (the
    footprint truth's rays per texel side, and how far the last doubling moved the
    scores of the all-off run: converged below 0.1 dB), ``render_scale``.
    """
    size = 32 if quick else 64
    plans = plans if plans is not None else (("coarse",) if quick else ("coarse", "medium"))
    unknown = [s for s in scenes if s not in SCENES] + [p for p in plans if p not in PLANS]
    unknown += [p for p in processings if p not in PROCESSINGS]
    if render_scale is not None and not 0 < render_scale <= MAX_RENDER_SCALE:
        raise RigError(f"render_scale={render_scale}: valid is 0 < scale ≤ "
                       f"{MAX_RENDER_SCALE:g} (the camera's 1)")  # fmt: skip
    if truth_rays < 8:
        raise RigError(f"truth_rays={truth_rays}: valid is ≥ 8 (the truth starts at 4 rays)")
    if unknown or not processings:
        raise RigError(
            f"unknown scene, plan or processing {unknown}; valid scenes {list(SCENES)}, "
            f"plans {list(PLANS)}, processings {list(PROCESSINGS)} (at least one)"
        )
    rows = []
    for name in scenes:
        with contextlib.ExitStack() as stack:
            sim = stack.enter_context(Simulator(scene_from_dict(SCENES[name])))
            for plan in plans:
                rows += _plan_rows(name, plan, sim, size, runs, processings,
                                   render_scale=render_scale, truth_rays=truth_rays)  # fmt: skip
    return rows


def _sensor(archive: Path, material, scene, config: RigConfig, filter: str) -> dict:
    """What :func:`studies.noise_floor.floor_db` needs of a session besides the truth:
    each captured pair's noise gain and exposure, and the sensor."""
    btf, valid = material.btf, np.asarray(material.btf_slot_valid, bool)
    pairs = captured_pairs(btf, valid, HELD_OUT)
    gains, exposures = capture_gains(archive, pairs, size=material.size, filter=filter)
    camera = config.camera_arc.cameras[0]  # the default rig's cameras share one sensor
    noise = scene.spec.params("noise") if scene.has("noise") else None
    return {"gains": gains, "exposure_s": exposures, "bit_depth": camera.bit_depth,
            "channels": camera.channels, "noise": noise}  # fmt: skip


def _plan_rows(
    name: str, plan: str, sim: Simulator, size: int, runs, processings, *,
    render_scale: float | None = None, truth_rays: int = 32,
) -> list[dict]:  # fmt: skip
    measured = {}
    lights = len(parse_plan(plan_toml(plan)).captures.btf.lights.resolve().directions)
    sessions: dict[tuple, list] = {}  # runs that differ in registration share the frames
    for off in runs:
        sessions.setdefault(tuple(t for t in off if t not in REGISTRATION_TERMS), []).append(off)
    for scene_off, group in sessions.items():
        scene = scene_from_dict(scene_without(name, scene_off, render_scale=render_scale))
        with tempfile.TemporaryDirectory(prefix="rig-error-budget-") as tmp:
            archive, config = record(scene, plan_toml(plan), Path(tmp))
            scale = irradiance_scale(scene, config)
            for off in group:
                options = {k: v for t in off for k, v in REGISTRATION_TERMS.get(t, {}).items()}
                # as many components as lights: the per-view PCA is then lossless
                for way in processings:
                    material = process(archive, size=size, components=lights,
                                       **PROCESSINGS[way], **options)  # fmt: skip
                    sensor = _sensor(archive, material, scene, config, options.get("filter", "box"))
                    measured[off, way] = (material, scale, sensor)
    strictest = max(runs, key=len)  # the highest scores ask the most of the truth
    first = measured[strictest, processings[-1]]
    held_truth, captured_truth, rays, change = _converged(first[0], sim, first[1], truth_rays)
    rows = []
    for off in runs:
        for way in processings:
            material, scale, sensor = measured[off, way]
            lossless = components_of(material.btf)
            for c, label in ((COMPONENTS, COMPONENTS), (lossless, "lossless")):
                rows.append({
                    "scene": name, "plan": plan, "run": _label(off), "off": list(off),
                    "processing": way, "components": label,
                    **_scores(material, scale, (held_truth, captured_truth), c, sensor),
                    "truth_rays": rays, "truth_change_db": change,
                    "render_scale": SCENES[name]["render"]["scale"] if render_scale is None
                    else render_scale,
                })  # fmt: skip
    return rows


def plot(rows: list[dict], path: str | Path) -> None:
    """The waterfall: one panel per (plan, scene), one group of bars per run and
    processing (``corrected``: the near-lamp irradiance per texel divided out), PSNR
    at the captured pairs and at the held-out directions, at c and lossless."""
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    plans = list(dict.fromkeys(r["plan"] for r in rows))
    groups = len({(r["run"], r["processing"]) for r in rows})  # bars' groups in a panel
    fig = Figure(figsize=(max(5.5, 0.45 * groups) * len(scenes), 4.4 * len(plans)))
    axes = np.array(fig.subplots(len(plans), len(scenes), sharey=True, squeeze=False))
    series = (("psnr_captured_db", "lossless", "captured, lossless"),
              ("psnr_captured_db", COMPONENTS, f"captured, c = {COMPONENTS}"),
              ("psnr_held_out_db", "lossless", "held out, lossless"),
              ("psnr_held_out_db", COMPONENTS, f"held out, c = {COMPONENTS}"))  # fmt: skip
    low = min(r[key] for r in rows for key in ("psnr_captured_db", "psnr_held_out_db"))
    for (i, plan), (j, scene) in itertools.product(enumerate(plans), enumerate(scenes)):
        ax = axes[i, j]
        sel = [r for r in rows if (r["scene"], r["plan"]) == (scene, plan)]
        runs = list(dict.fromkeys((r["run"], r["processing"]) for r in sel))
        x = np.arange(len(runs))
        for k, (key, c, label) in enumerate(series):
            values = [next(r[key] for r in sel
                           if (r["run"], r["processing"]) == run and r["components"] == c)
                      for run in runs]  # fmt: skip
            ax.bar(x + (k - 1.5) * 0.2, values, 0.2, label=label)
        short = {"irradiance per texel": "corrected"}  # the default processing's label is long
        ax.set_xticks(x, [f"{run}, {short.get(p, p)}" for run, p in runs],
                      rotation=35, ha="right", fontsize=7)  # fmt: skip
        ax.set_ylim(np.floor(low) - 2, None)
        ax.set_title(f"{scene}, {plan} plan", fontsize=9)
        ax.grid(axis="y", alpha=0.3)
        ax.set_ylabel("PSNR against the footprint truth (dB)", fontsize=8)
    axes[0, 0].legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
