"""``rig bench render-loop``: the renderer's loop closed against the simulator.

A simulated sample (the bumps, the weave) is measured by a session on the
simulated rig in virtual time (``run_local``), processed by the ``btf``
stage (registration, per-view PCA), and the material is rendered on a flat
quad at light and view directions that no plan captured. Each image is
compared texel by texel with the simulator's noise-free BTF of the true
sample at the same directions, averaged over each texel's footprint
(``Simulator.btf_truth``, ray cast, never the rasteriser; as many rays per
texel as the score needs, ``studies.footprint``). The rows put the PSNR
beside each plan's capture time from the session estimate (``rig plan
--estimate``): what accuracy costs in time.

It runs the simulator, the processing and the renderer side by side, so it
lives on top of all three.
"""

from __future__ import annotations

import contextlib
import dataclasses
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter

from orchestrator.local import run_local
from processing.btf import (
    CompressedBTF,
    direction_weights,
    interpolate,
    light_weights,
    psnr_db,
    reconstruct,
    rmse,
)
from processing.offline import BtfStage, PbrStage, run_stages
from render import DirectionalLight, Renderer
from render.texel_view import texel_camera, texel_quad
from rig.clock import VirtualClock
from rig.config import RigConfig
from rig.errors import RigError
from rig.geometry import Sampling, angular_distance_deg, direction_vector
from rig.material import Material, read_material
from rig.plan import parse_plan
from rig.schedule import compile_plan
from sim.rig import SimulatedRig
from sim.scene import Scene, scene_from_dict
from sim.simulator import Simulator
from studies.footprint import FootprintTruth, converged_truth, truth_at

__all__ = [
    "HELD_OUT",
    "PLANS",
    "SCENES",
    "LoopTruth",
    "captured_pairs",
    "gaps_deg",
    "interpolated",
    "interpolation_bound",
    "irradiance_scale",
    "loop_truth",
    "measure",
    "patient_cameras",
    "plan_directions",
    "plot",
    "process",
    "reconstructed",
    "record",
    "run",
    "scores",
    "truncated",
]

#: The samples: the examples' bumps and weave, with sensor noise (a measurement,
#: not the truth) and the weave's specular yarns.
SCENES: dict[str, dict] = {
    "bumps": {
        "effects": ["shadows", "noise"],
        "sample": {"generator": "bumps", "depth_mm": 2.0, "materials": ["paint"],
                   "params": {"amplitude_mm": 1.2, "spacing_mm": 8.0, "sigma_mm": 1.6}},
        "materials": {"paint": {"albedo": {"kind": "checker", "rgb_a": [0.8, 0.8, 0.75],
                                           "rgb_b": [0.5, 0.55, 0.6], "period_mm": 16.0}}},
        "render": {"scale": 0.5},
    },
    "weave": {
        "effects": ["shadows", "specular", "noise"],
        "sample": {"generator": "weave", "depth_mm": 3.0, "materials": ["warp", "weft"],
                   "params": {"pitch_mm": 5.0, "width_mm": 3.4, "thickness_mm": 1.2,
                              "crimp_mm": 0.6}},
        "materials": {
            "warp": {"albedo": {"kind": "noise", "rgb": [0.75, 0.45, 0.2], "variation": 0.2,
                                "scale_mm": 3.0},
                     "specular": {"model": "phong", "ks": 0.08, "exponent": 25.0}},
            "weft": {"albedo": {"kind": "constant", "rgb": [0.2, 0.35, 0.6]},
                     "specular": {"model": "lafortune",
                                  "lobes": [{"cx": -1.0, "cy": -1.0, "cz": 1.0, "n": 15.0,
                                             "rho": 0.15}]}},
        },
        "render": {"scale": 0.5},
    },
}  # fmt: skip

#: Plans from coarse to the seed's H1: view and light rings as (θ, Δφ) degrees
#: (Δφ = 0: the single frontal direction), at the default rig's camera and lamp
#: polar angles so the rig realises them exactly; or a named sampling.
PLANS: dict[str, tuple] = {
    "coarse": (((0, 0), (45, 90)), ((15, 120), (45, 90))),
    "medium": (((0, 0), (30, 60), (60, 45)), ((15, 120), (30, 60), (45, 45), (60, 60))),
    "fine": (
        ((0, 0), (15, 90), (30, 45), (45, 45), (60, 45)),
        ((15, 60), (30, 45), (45, 36), (60, 45)),
    ),
    "H1": ("H1", "H1"),
}

#: (view, light) pairs, (θ, φ) degrees in the sample frame, between the
#: directions of every plan (the rows report how far the nearest captured one is).
HELD_OUT: tuple[tuple[tuple[float, float], tuple[float, float]], ...] = (
    ((22.0, 75.0), (38.0, 200.0)),
    ((38.0, 290.0), (24.0, 20.0)),
    ((12.0, 160.0), (52.0, 110.0)),
    ((40.0, 20.0), (38.0, 320.0)),
)


def _ring_directions(spec) -> list[tuple[float, float]]:
    """(θ, φ) degrees of a plan's rings ((θ, Δφ) pairs; Δφ = 0: the single direction)."""
    return [(float(theta), float(phi)) for theta, dphi in spec
            for phi in ([0.0] if dphi == 0 else np.arange(0.0, 360.0, dphi))]  # fmt: skip


def _sampling_toml(spec) -> str:
    if isinstance(spec, str):
        return f'"{spec}"'
    return "[" + ", ".join(f"[{t}, {p:g}]" for t, p in _ring_directions(spec)) + "]"


def plan_directions(name: str) -> tuple[np.ndarray, np.ndarray]:
    """The nominal (θ, φ) degrees of ``PLANS[name]``: views (n, 2) and lights (m, 2)."""
    if name not in PLANS:
        raise RigError(f"plan {name!r}: valid are {list(PLANS)}")
    return tuple(
        Sampling.named(spec).directions if isinstance(spec, str)
        else np.array(_ring_directions(spec))
        for spec in PLANS[name]
    )  # fmt: skip


def interpolation_bound(sim: Simulator, plan: str, size: int, held_out, *, rays: int = 4,
                        light_blend: str = "cosine") -> dict:  # fmt: skip
    """What interpolation alone costs: the truth at the plan's nominal directions (a
    measurement without error) blended to the held-out pairs as
    ``processing.btf.interpolate`` blends a material (the 4 nearest, Shepard), scored
    against the truth there (peak: its maximum, PSNR dB). ``both``: views and lights
    blended; ``lights only``: the truth at each held-out view, its lights blended;
    ``views only``: at each held-out light, its views blended. ``light_blend``:
    ``"cosine"`` (the weights carry the light's cosine, as the material's do) or
    ``"plain"`` (weights that sum to 1)."""
    if light_blend not in ("cosine", "plain"):
        raise RigError(f"light_blend={light_blend!r}: valid are 'cosine', 'plain'")
    views, lights = plan_directions(plan)
    view_vectors, light_vectors = (direction_vector(*d.T) for d in (views, lights))
    weights = light_weights if light_blend == "cosine" else direction_weights
    truth = {}  # (view, light) → the footprint truth, each computed once

    def at(view, light) -> np.ndarray:
        key = (tuple(view), tuple(light))
        if key not in truth:
            truth[key] = sim.btf_truth(view, light, size, rays=rays).astype(np.float64)
        return truth[key]

    held = np.stack([at(v, light) for v, light in held_out])
    blends: dict[str, list] = {"both": [], "lights only": [], "views only": []}
    for view, light in held_out:
        vs = list(zip(*direction_weights(view_vectors, view, method="nearest4"), strict=True))
        ls = list(zip(*weights(light_vectors, light, method="nearest4"), strict=True))
        blends["both"].append(sum(a * b * at(views[j], lights[i]) for j, a in vs for i, b in ls))
        blends["lights only"].append(sum(b * at(view, lights[i]) for i, b in ls))
        blends["views only"].append(sum(a * at(views[j], light) for j, a in vs))
    peak = float(held.max())
    return {name: round(psnr_db(rmse(np.stack(b), held), peak=peak), 2)
            for name, b in blends.items()}  # fmt: skip


def plan_toml(name: str) -> str:
    """The session plan of ``PLANS[name]``: a BTF capture, one exposure."""
    views, lights = PLANS[name]
    return (
        f'[sample]\nname = "loop-{name.lower()}"\n[captures.btf]\n'
        f"views = {_sampling_toml(views)}\nlights = {_sampling_toml(lights)}\n"
        "[exposure]\nexposure_s = 0.05\n"
    )


def patient_cameras(config: RigConfig) -> RigConfig:
    """The simulated cameras render each frame on this machine's CPU, which a loaded
    machine can slow past a real camera's 1 s timeout: wait up to a minute."""
    cameras = []
    for cam in config.camera_arc.cameras:
        retry = cam.connection.retry.model_copy(update={"timeout_s": 60.0})
        connection = cam.connection.model_copy(update={"retry": retry})
        cameras.append(cam.model_copy(update={"connection": connection}))
    arc = config.camera_arc.model_copy(update={"cameras": tuple(cameras)})
    return config.model_copy(update={"camera_arc": arc})


def measure(scene: Scene, plan_text: str, folder: Path, *, size: int, components: int):
    """Run the plan on the simulated rig, process its BTF; (material, rig config)."""
    archive, config = record(scene, plan_text, folder)
    return process(archive, size=size, components=components), config


def record(
    scene: Scene,
    plan_text: str,
    folder: Path,
    *,
    on_event: Callable[[dict], None] | None = None,
) -> tuple[Path, RigConfig]:
    """Run the plan on the simulated rig in virtual time; (archive, rig config).
    ``on_event`` sees the session's events (``run_local``), e.g. for a progress bar."""
    plan_path, archive = folder / "plan.toml", folder / "session.zarr"
    plan_path.write_text(plan_text)
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as rig:
        config = patient_cameras(rig.rig_config())
        final = run_local(plan_path, config, archive=archive, clock=clock, on_fault="fail",
                          on_event=on_event)  # fmt: skip
    if final.get("state") != "done":
        raise RigError(f"the simulated session of {plan_path} ended {final.get('state')}: {final}")
    return archive, config


def process(archive: Path, *, size: int, components: int, raw: bool = False, **options) -> Material:
    """The archive's ``btf`` stage (``raw``: without the calibration's corrections;
    ``options``: more :class:`~processing.offline.BtfStage` fields; with ``"model"``
    directions the ``pbr`` stage is fitted to the stage's nominal output first)."""
    stage = BtfStage(size=size, components=components, raw=raw, **options)
    if "model" in (stage.lights, stage.views):  # the model is fitted to the BTF as measured
        run_stages(archive, [BtfStage(size=size, components=components, raw=raw), PbrStage()],
                   workers=1)  # fmt: skip
    run_stages(archive, [stage], workers=1)
    return read_material(archive)


def truncated(btf: CompressedBTF, c: int) -> CompressedBTF:
    """The first ``c`` components of a per-view PCA: the same model the btf stage
    makes with ``components=c`` (the components come in descending order of λ)."""
    return dataclasses.replace(
        btf, basis=btf.basis[:, :c], weights=btf.weights[:, :, :c],
        rank=np.minimum(btf.rank, c).astype(np.int32),
    )  # fmt: skip


def _valid_slots(btf: CompressedBTF, valid: np.ndarray) -> CompressedBTF:
    """The view slots that hold data: what the renderer blends over."""
    return dataclasses.replace(
        btf, view_dirs_deg=btf.view_dirs_deg[valid], mean=btf.mean[valid],
        basis=btf.basis[valid], weights=btf.weights[valid],
        singular_values=btf.singular_values[valid], rank=btf.rank[valid],
    )  # fmt: skip


def rendered_at(material: Material, held_out) -> np.ndarray:
    """(pairs, N, N, 3) float32: the material on a texel-exact quad at each (view, light)."""
    camera = texel_camera(material.sample_mm, material.size)
    images = []
    for view_deg, light_deg in held_out:
        mesh, frame = texel_quad(material.sample_mm, view_deg)
        light = DirectionalLight(tuple(frame @ direction_vector(*light_deg)))
        with Renderer(material, mesh, shadows=False) as renderer:
            images.append(renderer.render(camera, [light]))
    return np.stack(images)


def irradiance_scale(scene: Scene, config: RigConfig) -> float:
    """Stored BTF value per unit of ``btf_truth``, from the radiometry.

    The btf stage stores DN / (full scale · exposure) = radiance /
    ``full_scale_exposure``; a lamp of radiant intensity I at the light arc's
    radius r gives the sample the irradiance I / r², and radiance = truth ×
    irradiance. (All lamps of the default rig have relative intensity 1.)
    """
    radiometry = scene.spec.radiometry
    lamp = config.light_arc.lamps[0]
    radius_m = config.light_arc.radius_mm / 1000.0
    irradiance = radiometry.intensity_w_sr * lamp.intensity / radius_m**2
    return irradiance / radiometry.full_scale_exposure


def interpolated(btf: CompressedBTF, valid: np.ndarray, pairs) -> np.ndarray:
    """(pairs, N, N, 3): ``processing.btf.interpolate`` over the valid view slots."""
    reference = _valid_slots(btf, valid)
    return np.stack([interpolate(reference, view_deg=v, light_deg=light) for v, light in pairs])


def reconstructed(btf: CompressedBTF, pairs) -> np.ndarray:
    """(pairs, N, N, 3): the model at (view slot, light) index pairs."""
    return np.stack([reconstruct(btf, view=j, light=i) for j, i in pairs])


def _gap_deg(held: np.ndarray, table_deg: np.ndarray) -> float:
    """The smallest angle between a held-out direction and a captured one."""
    a = direction_vector(held[:, None, 0], held[:, None, 1])
    b = direction_vector(table_deg[None, :, 0], table_deg[None, :, 1])
    return float(angular_distance_deg(a, b).min())


def _nearest(table_deg: np.ndarray, query_deg) -> int:
    v = direction_vector(*query_deg)
    return int(np.argmin(angular_distance_deg(direction_vector(*table_deg.T), v)))


def captured_pairs(btf: CompressedBTF, valid: np.ndarray, held_out) -> list[tuple[int, int]]:
    """(valid view slot, light) of the captured pair nearest each held-out one."""
    slots = np.flatnonzero(valid)
    return [(int(slots[_nearest(btf.view_dirs_deg[slots], v)]),
             _nearest(btf.light_dirs_deg, light)) for v, light in held_out]  # fmt: skip


@dataclass(frozen=True)
class LoopTruth:
    """The footprint truths a measured material is scored against.

    held_out : the truth at the held-out (view, light) pairs
    captured : the truth at the captured pair nearest each held-out one
    pairs : (valid view slot, light) index of those captured pairs
    peak : every PSNR's peak: the held-out truth's maximum, all pairs pooled
    """

    held_out: FootprintTruth
    captured: FootprintTruth
    pairs: list[tuple[int, int]]
    peak: float


def loop_truth(material: Material, sim: Simulator, scale: float, held_out, *,
               components: int, most: int = 32) -> LoopTruth:  # fmt: skip
    """The truths at ``held_out`` and the captured pairs nearest them, converged on
    the scores of ``components`` components (smaller c share them: their errors are
    larger, so the truth's own error weighs less in them), with at most ``most`` rays
    per texel side."""
    btf, valid = material.btf, np.asarray(material.btf_slot_valid, bool)
    pairs = captured_pairs(btf, valid, held_out)
    captured_dirs = [(btf.view_dirs_deg[j], btf.light_dirs_deg[i]) for j, i in pairs]
    full = truncated(btf, components)
    own = converged_truth(sim, held_out, interpolated(full, valid, held_out) / scale, most=most)
    peak = float(own.values.max())
    at_captured = converged_truth(sim, captured_dirs, reconstructed(full, pairs) / scale,
                                  peak=peak, most=most)  # fmt: skip
    return LoopTruth(own, at_captured, pairs, peak)


def scores(material: Material, truth: LoopTruth, scale: float, held_out, *, c: int) -> dict:
    """The material's first ``c`` components against ``truth``: ``psnr_cpu_db``
    (``processing.btf.interpolate`` at the held-out pairs) and ``psnr_captured_db``
    (the model at the captured pairs nearest them: the measurement's own error)."""
    btf, valid = material.btf, np.asarray(material.btf_slot_valid, bool)
    model = truncated(btf, c)
    cpu = interpolated(model, valid, held_out) / scale
    measured = reconstructed(model, truth.pairs) / scale
    return {
        "psnr_cpu_db": round(psnr_db(rmse(cpu, truth.held_out.values), peak=truth.peak), 2),
        "psnr_captured_db": round(
            psnr_db(rmse(measured, truth.captured.values), peak=truth.peak), 2
        ),
    }


def gaps_deg(material: Material, held_out) -> tuple[float, float]:
    """(view, light): the closest approach of a held-out direction to a captured one, °."""
    btf, valid = material.btf, np.asarray(material.btf_slot_valid, bool)
    views = np.array([v for v, _ in held_out], float)
    lights = np.array([light for _, light in held_out], float)
    return _gap_deg(views, btf.view_dirs_deg[valid]), _gap_deg(lights, btf.light_dirs_deg)


def _rows(name, plan, material, sims, scale, components, held_out, capture_s):
    btf, valid = material.btf, np.asarray(material.btf_slot_valid, bool)
    truth = loop_truth(material, sims[0], scale, held_out, components=max(components))
    own, peak = truth.held_out, truth.peak
    other = truth_at(sims[1], held_out, material.size, own.rays)
    view_gap, light_gap = gaps_deg(material, held_out)
    rows = []
    for c in components:
        model = truncated(btf, c)
        rendered = rendered_at(dataclasses.replace(material, btf=model), held_out) / scale
        cpu = interpolated(model, valid, held_out) / scale
        fit = float(np.sum(rendered * own.values) / np.sum(rendered * rendered))
        rows.append({
            "scene": name, "plan": plan, "views": int(valid.sum()),
            "lights": len(btf.light_dirs_deg), "frames": int(valid.sum()) * len(btf.light_dirs_deg),
            "capture_s": round(capture_s, 1), "components": c,
            "psnr_db": round(psnr_db(rmse(rendered, own.values), peak=peak), 2),
            **scores(material, truth, scale, held_out, c=c),
            "render_vs_cpu": float(np.abs(rendered - cpu).max() / peak),
            "psnr_other_sample_db": round(psnr_db(rmse(rendered, other), peak=peak), 2),
            "truth_rays": max(own.rays, truth.captured.rays),
            "truth_converged": own.converged and truth.captured.converged,
            "scale_fit_ratio": round(1.0 / fit, 4),
            "view_gap_deg": round(view_gap, 1), "light_gap_deg": round(light_gap, 1),
        })  # fmt: skip
    return rows


def run(
    quick: bool = False,
    *,
    scenes: tuple[str, ...] = tuple(SCENES),
    plans: tuple[str, ...] | None = None,
) -> list[dict]:
    """Rows, one per (scene, plan, c): ``scene``, ``plan``, ``views`` (valid
    view slots) × ``lights`` = ``frames`` captured, ``capture_s`` (the
    session estimate on the scene's rig), ``components`` c, ``psnr_db`` of the
    rendered material against the truth at the held-out (view, light) pairs
    (peak: the truth's maximum, all pairs pooled), ``psnr_cpu_db`` of
    ``processing.btf.interpolate`` the same way, ``psnr_captured_db`` (the
    material at the captured pair nearest each held-out one against the truth
    there: the measurement's own error, no interpolation), ``render_vs_cpu`` (largest
    difference over the peak), ``psnr_other_sample_db`` (the rendering against
    the *other* sample's truth: what an unrelated material scores),
    ``scale_fit_ratio`` (least-squares scale over the derived one, see
    :func:`irradiance_scale`), ``view_gap_deg`` / ``light_gap_deg`` (closest
    approach of a held-out direction to a captured one), ``truth_rays`` (rays per
    texel side of the footprint truth, :func:`studies.footprint.converged_truth`
    at the largest c) and ``truth_converged`` (doubling them changed both scores by
    < 0.1 dB).

    ``quick``: 32² texels, the first two held-out pairs, c ∈ {2, 6}, the
    coarse plan; else 64² texels, all four pairs, c ∈ {2, 4, 8}, all plans.
    ``scenes``, ``plans``: which of :data:`SCENES` and :data:`PLANS` to run.
    """
    size, held_out = (32, HELD_OUT[:2]) if quick else (64, HELD_OUT)
    components = (2, 6) if quick else (2, 4, 8)
    plans = plans if plans is not None else (("coarse",) if quick else tuple(PLANS))
    unknown = [s for s in scenes if s not in SCENES] + [p for p in plans if p not in PLANS]
    if unknown:
        raise RigError(
            f"unknown scene or plan {unknown}; valid scenes {list(SCENES)}, plans {list(PLANS)}"
        )
    loaded = {name: scene_from_dict(spec) for name, spec in SCENES.items()}
    rows = []
    with contextlib.ExitStack() as stack:
        sims = {name: stack.enter_context(Simulator(scene)) for name, scene in loaded.items()}
        for name in scenes:
            other = next(s for s in SCENES if s != name)
            for plan in plans:
                text = plan_toml(plan)
                with tempfile.TemporaryDirectory(prefix="rig-render-loop-") as tmp:
                    material, config = measure(
                        loaded[name], text, Path(tmp), size=size, components=max(components)
                    )
                    capture_s = compile_plan(parse_plan(text), config).estimate.total_s
                    rows += _rows(name, plan, material, (sims[name], sims[other]),
                                  irradiance_scale(loaded[name], config), components, held_out,
                                  capture_s)  # fmt: skip
    return rows


def plot(rows: list[dict], path: str | Path) -> None:
    """PSNR at the held-out directions against the plan's capture time, one line
    per c, one panel per scene; dashed: the material at the captured pairs nearest
    the held-out ones (the measurement's floor), dotted: the other sample's score."""
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    longest = max(r["capture_s"] for r in rows) / 60
    fig = Figure(figsize=(5 * len(scenes), 3.8))
    axes = np.atleast_1d(fig.subplots(1, len(scenes), sharey=True))
    for ax, scene in zip(axes, scenes, strict=True):
        sel = [r for r in rows if r["scene"] == scene]
        for c in dict.fromkeys(r["components"] for r in sel):
            line = sorted((r for r in sel if r["components"] == c), key=lambda r: r["capture_s"])
            ax.plot([r["capture_s"] / 60 for r in line], [r["psnr_db"] for r in line], "o-",
                    label=f"c = {c}")  # fmt: skip
        first = [r for r in sel if r["components"] == sel[0]["components"]]
        first.sort(key=lambda r: r["capture_s"])
        most = max(r["components"] for r in sel)
        floor = sorted((r for r in sel if r["components"] == most), key=lambda r: r["capture_s"])
        ax.plot([r["capture_s"] / 60 for r in floor], [r["psnr_captured_db"] for r in floor],
                "k--", label=f"at the nearest captured pairs, c = {most}")  # fmt: skip
        ax.plot([r["capture_s"] / 60 for r in first], [r["psnr_other_sample_db"] for r in first],
                ":", color="gray", label="another sample")  # fmt: skip
        for k, r in enumerate(first):  # above and below in turn: plans may cost alike
            ax.annotate(f"{r['plan']} ({r['frames']} frames)", (r["capture_s"] / 60, r["psnr_db"]),
                        textcoords="offset points", xytext=(-30, 8 if k % 2 else -14),
                        fontsize=7)  # fmt: skip
        ax.set_title(f"{scene}: rendered vs the simulator's truth at held-out directions")
        ax.set_xscale("log")  # plans from a minute and a half (coarse) to an hour (H1)
        ax.xaxis.set_minor_formatter(NullFormatter())
        ticks = [t for t in (1, 2, 5, 10, 20, 50, 100, 200) if t <= 2 * longest]
        ax.set_xticks(ticks, labels=[str(t) for t in ticks])
        ax.set_xlabel("capture time, session estimate (min, log scale)")
        ax.title.set_fontsize(9)
        ax.legend(fontsize=8, loc="lower right")
    axes[0].set_ylabel("PSNR (dB)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
