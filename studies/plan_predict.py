"""``rig plan PLAN --predict``: a plan's accuracy before the rig spends its time on it.

The plan's BTF capture runs in virtual time on the simulated rig with a proxy
sample (the render loop's bumps or weave, or a scene file), through the
daemon, and the ``btf`` stage processes the session; the material is scored
against the simulator's footprint truth as the render loop scores it
(:func:`studies.render_loop.scores`): at the captured pairs nearest the
held-out directions (the measurement's own error) and at the held-out
directions (what interpolating between the plan's directions adds), per
component count c.

Only what the scores read is simulated: the view slots the held-out views
blend and the captured pairs lie in (:func:`scored_views`), each with all of
the plan's lights, one exposure per frame. The btf stage compresses each view
slot from its own frames alone, so the scores are the whole plan's, up to the
sensor noise's draws (they follow the frame order) and float16 rounding
(tests/studies/test_plan_predict.py); the duration and data size come from the
whole plan's estimate.

It runs at a reduced resolution (:data:`SENSOR_SCALE`, :data:`TEXELS`): a
quarter of the sensor (256 × 192 pixels of the default rig's 1024 × 768) and
32² texels, the render loop's 8 pixels per texel side (half the sensor, 64²
texels) at a quarter of its texels. An eighth of the sensor costs about the
same and its markers are too small to register at 45° views; at a quarter,
views up to θ = 51° register and some at 68° do not (the table counts the
registered view slots of those read). docs/geometry.md sets the prediction
beside the render loop's numbers.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tomli_w

from rig.config import RigConfig
from rig.errors import ConfigError, RigError
from rig.geometry import angular_distance_deg, direction_vector
from rig.material import Material
from rig.plan import Plan, parse_plan
from rig.schedule import compile_plan
from rig.tomlfile import read_toml
from sim.scene import Scene, scene_from_dict
from sim.simulator import Simulator
from studies.render_loop import (
    HELD_OUT,
    SCENES,
    gaps_deg,
    irradiance_scale,
    loop_truth,
    process,
    record,
    scores,
)

__all__ = [
    "BLENDED",
    "COMPONENTS",
    "SENSOR_SCALE",
    "TEXELS",
    "Prediction",
    "btf_only",
    "predict",
    "proxy_scene",
    "scored_views",
]

#: The simulated cameras' image size as a fraction of the rig's sensors.
SENSOR_SCALE = 0.25
#: Texels per side of the processed BTF.
TEXELS = 32
#: The component counts c scored (the btf stage keeps the largest).
COMPONENTS = (2, 4, 8)
#: View slots ``processing.btf.interpolate`` blends at a held-out view (``nearest4``).
BLENDED = 4
#: Directions this close to the farthest one blended are read too (a tie there).
_TIE_DEG = 1e-6


@dataclass(frozen=True)
class Prediction:
    """A plan's predicted accuracy on a proxy sample.

    views : view slots registered of those recorded (the others are left out of the
        material)
    recorded : view slots recorded: those the scores read (:func:`scored_views`)
    view_slots : view slots the plan captures
    captured_db : {c: PSNR (dB) of the material at the captured pairs nearest the
        held-out ones}
    held_out_db : {c: PSNR (dB) of the material interpolated at the held-out pairs}
    view_gap_deg, light_gap_deg : closest approach of a held-out direction to a
        captured one, degrees
    """

    views: int
    recorded: int
    view_slots: int
    captured_db: dict[int, float]
    held_out_db: dict[int, float]
    view_gap_deg: float
    light_gap_deg: float


def proxy_scene(sample: str) -> Scene:
    """The proxy sample at :data:`SENSOR_SCALE`: ``bumps`` or ``weave`` (the render
    loop's), else the path of a scene TOML file; a ``ConfigError`` names
    ``--sample`` and the valid values when it is neither."""
    if sample in SCENES:
        data, source, base = dict(SCENES[sample]), f"--sample {sample}", Path()
    else:
        path = Path(sample)
        if path.suffix != ".toml" or not path.is_file():
            raise ConfigError(
                f"--sample {sample!r}: give {' or '.join(SCENES)}, or a scene TOML file"
            )
        data, source, base = read_toml(path, "--sample scene"), str(path), path.parent
    render = data.get("render", {})
    data["render"] = {**(render if isinstance(render, dict) else {}), "scale": SENSOR_SCALE}
    return scene_from_dict(data, source=source, base_dir=base)


def btf_only(plan: Plan, views: np.ndarray | None = None) -> str:
    """The plan's TOML as the prediction records it: its BTF capture alone (the
    photometric-stereo and laser captures are not scored), at the cameras' full
    resolution (the proxy's cameras are the reduced ones, :data:`SENSOR_SCALE`),
    one exposure per frame (the btf stage reads a step's first bracket only:
    ``exposure_s`` × the first ``hdr_brackets``), and only the view directions
    ``views`` ((n, 2) θ, φ degrees; None: all of the plan's)."""
    btf = plan.captures.btf
    if views is not None:
        spec = type(btf.views)(directions=[(float(t), float(p)) for t, p in views])
        btf = btf.model_copy(update={"views": spec})
    captures = plan.captures.model_copy(update={"btf": btf, "ps": None, "mdf": None})
    exposure = plan.exposure.model_copy(update={
        "exposure_s": plan.exposure.exposure_s * plan.exposure.hdr_brackets[0],
        "hdr_brackets": (1.0,)})  # fmt: skip
    resolution = plan.resolution.model_copy(update={"scale": 1.0})
    proxy = plan.model_copy(
        update={"captures": captures, "exposure": exposure, "resolution": resolution}
    )
    return tomli_w.dumps(proxy.model_dump(mode="json", exclude_none=True))


def scored_views(views_deg: np.ndarray, held_out, *, failed=()) -> np.ndarray:
    """Indices, ascending, of the view directions the scores read.

    Per held-out view, ``processing.btf.interpolate`` blends the :data:`BLENDED`
    nearest registered view slots and the captured pair is the nearest one: every
    direction of ``views_deg`` (n, 2) (θ, φ degrees) as near as the
    :data:`BLENDED`-th nearest of those not in ``failed`` (indices of directions
    that did not register), ties included, is read.
    """
    vectors = direction_vector(views_deg[:, 0], views_deg[:, 1])
    usable = np.setdiff1d(np.arange(len(views_deg)), np.asarray(list(failed), int))
    read: set[int] = set()
    for view, _ in held_out:
        gaps = angular_distance_deg(vectors, direction_vector(*view))
        if len(usable):
            reach = np.sort(gaps[usable])[min(BLENDED, len(usable)) - 1]
            read |= {int(j) for j in usable[gaps[usable] <= reach + _TIE_DEG]}
    return np.array(sorted(read), int)


def predict(
    plan: Plan,
    scene: Scene,
    *,
    on_session: Callable[[int], None] | None = None,
    on_event: Callable[[dict], None] | None = None,
    on_stage: Callable[[str], None] | None = None,
) -> Prediction:
    """Record the plan's BTF capture at the view directions the scores read
    (:func:`scored_views`) on the simulated rig with ``scene``, process and score it.

    A view slot's material is its own frames' PCA, so the scores are those of the
    whole plan's capture up to the sensor noise's draws (docs/geometry.md). Where a
    read view slot does not register, the next nearest are recorded in its stead
    (one more session).

    ``on_session`` is told each session's step count as it starts, ``on_event``
    sees the session's events (a progress bar); ``on_stage`` is told
    ``"processing"`` and ``"scoring"`` as each begins.
    """
    views = plan.captures.btf.views.resolve().directions
    failed: set[int] = set()
    read = scored_views(views, HELD_OUT)
    while True:
        text = btf_only(plan, views[read])
        if on_session is not None:
            on_session(len(compile_plan(parse_plan(text), scene.rig).steps))
        with tempfile.TemporaryDirectory(prefix="rig-plan-predict-") as tmp:
            archive, config = record(scene, text, Path(tmp), on_event=on_event)
            if on_stage is not None:
                on_stage("processing")
            material = process(archive, size=TEXELS, components=max(COMPONENTS))
        failed |= set(read[~_registered(material, views[read])].tolist())
        wanted = scored_views(views, HELD_OUT, failed=failed)
        if set(wanted.tolist()) <= set(read.tolist()) or not len(wanted):
            break
        read = wanted
    if on_stage is not None:
        on_stage("scoring")
    return _score(material, scene, config, view_slots=len(views))


def _registered(material: Material, views_deg: np.ndarray) -> np.ndarray:
    """(n,) bool: which of the recorded view directions ``views_deg`` (n, 2) hold data."""
    valid = np.asarray(material.btf_slot_valid, bool)
    slots = material.btf.view_dirs_deg if material.btf is not None else np.zeros((0, 2))
    if not len(slots):
        return np.zeros(len(views_deg), bool)
    gaps = angular_distance_deg(
        direction_vector(slots[None, :, 0], slots[None, :, 1]),
        direction_vector(views_deg[:, None, 0], views_deg[:, None, 1]),
    )
    return valid[np.argmin(gaps, axis=1)]


def _score(material: Material, scene: Scene, config: RigConfig, *, view_slots: int) -> Prediction:
    valid = np.asarray(material.btf_slot_valid, bool)
    if material.btf is None or not valid.any():
        raise RigError(
            f"no view slot of the plan registered on the simulated {scene.source} at "
            f"{SENSOR_SCALE:g} of the sensor: there is no material to score"
        )
    scale = irradiance_scale(scene, config)
    with Simulator(scene) as sim:
        truth = loop_truth(material, sim, scale, HELD_OUT, components=max(COMPONENTS))
    rows = {c: scores(material, truth, scale, HELD_OUT, c=c) for c in COMPONENTS}
    view_gap, light_gap = gaps_deg(material, HELD_OUT)
    return Prediction(
        views=int(valid.sum()),
        recorded=len(valid),
        view_slots=view_slots,
        captured_db={c: row["psnr_captured_db"] for c, row in rows.items()},
        held_out_db={c: row["psnr_cpu_db"] for c, row in rows.items()},
        view_gap_deg=view_gap,
        light_gap_deg=light_gap,
    )
