"""``rig plan PLAN --predict``: a plan's accuracy before the rig spends its time on it.

The plan runs in virtual time on the simulated rig with a proxy sample (the
render loop's bumps or weave, or a scene file), through the daemon, and the
``btf`` stage processes the session; the material is scored against the
simulator's footprint truth as the render loop scores it
(:func:`studies.render_loop.scores`): at the captured pairs nearest the
held-out directions (the measurement's own error) and at the held-out
directions (what interpolating between the plan's directions adds), per
component count c.

It runs at a reduced resolution (:data:`SENSOR_SCALE`, :data:`TEXELS`): a
quarter of the sensor (256 × 192 pixels of the default rig's 1024 × 768) and
32² texels, the render loop's 8 pixels per texel side (half the sensor, 64²
texels) at a quarter of its texels. An eighth of the sensor costs about the
same and its markers are too small to register at 45° views; at a quarter,
views up to θ = 51° register and some at 68° do not (the table counts the
registered view slots). docs/geometry.md sets the prediction beside the
render loop's numbers.
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
from rig.material import Material
from rig.plan import Plan
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
    "COMPONENTS",
    "SENSOR_SCALE",
    "TEXELS",
    "Prediction",
    "btf_only",
    "predict",
    "proxy_scene",
]

#: The simulated cameras' image size as a fraction of the rig's sensors.
SENSOR_SCALE = 0.25
#: Texels per side of the processed BTF.
TEXELS = 32
#: The component counts c scored (the btf stage keeps the largest).
COMPONENTS = (2, 4, 8)


@dataclass(frozen=True)
class Prediction:
    """A plan's predicted accuracy on a proxy sample.

    views : view slots registered (the others are left out of the material)
    view_slots : view slots the plan captured
    captured_db : {c: PSNR (dB) of the material at the captured pairs nearest the
        held-out ones}
    held_out_db : {c: PSNR (dB) of the material interpolated at the held-out pairs}
    view_gap_deg, light_gap_deg : closest approach of a held-out direction to a
        captured one, degrees
    """

    views: int
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


def btf_only(plan: Plan) -> str:
    """The plan's TOML without its photometric-stereo and laser captures, which the
    prediction does not score, and at the cameras' full resolution: the proxy's
    cameras are the reduced ones (:data:`SENSOR_SCALE`)."""
    captures = plan.captures.model_copy(update={"ps": None, "mdf": None})
    resolution = plan.resolution.model_copy(update={"scale": 1.0})
    proxy = plan.model_copy(update={"captures": captures, "resolution": resolution})
    return tomli_w.dumps(proxy.model_dump(mode="json", exclude_none=True))


def predict(
    plan: Plan,
    scene: Scene,
    *,
    on_event: Callable[[dict], None] | None = None,
    on_stage: Callable[[str], None] | None = None,
) -> Prediction:
    """Run the plan's BTF capture on the simulated rig with ``scene``, process and score it.

    ``on_event`` sees the session's events (a progress bar); ``on_stage`` is told
    ``"processing"`` and ``"scoring"`` as each begins.
    """
    with tempfile.TemporaryDirectory(prefix="rig-plan-predict-") as tmp:
        archive, config = record(scene, btf_only(plan), Path(tmp), on_event=on_event)
        if on_stage is not None:
            on_stage("processing")
        material = process(archive, size=TEXELS, components=max(COMPONENTS))
    if on_stage is not None:
        on_stage("scoring")
    return _score(material, scene, config)


def _score(material: Material, scene: Scene, config: RigConfig) -> Prediction:
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
        view_slots=len(valid),
        captured_db={c: row["psnr_captured_db"] for c, row in rows.items()},
        held_out_db={c: row["psnr_cpu_db"] for c, row in rows.items()},
        view_gap_deg=view_gap,
        light_gap_deg=light_gap,
    )
