"""A fixed sequence of frames of the default scene at 1/16 scale, and its references.

``reference_frames.npz`` (beside this file) holds the frames the simulator gave
before it reused hits, visibility and shading between frames, with the scene's
noise (then drawn from the exact Poisson law); ``reference_clean_frames.npz``
the same sequence without the noise effect. The test in ``test_frame_reuse.py``
renders the sequence and compares. The order is part of the sequence: the noise
stream of each camera advances per frame.

Regenerate (only when the image formation is meant to change; ``--clean`` for
the noise-free one)::

    PYTHONPATH=. python -m tests.sim.frame_sequence tests/sim/data/reference_frames.npz
"""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path

import numpy as np

from sim import Simulator, scene_from_dict

REFERENCE = Path(__file__).parent / "data" / "reference_frames.npz"
CLEAN_REFERENCE = Path(__file__).parent / "data" / "reference_clean_frames.npz"
DEFAULT_SCENE = Path(__file__).parents[2] / "examples" / "scenes" / "default.toml"

# (camera, turntable °, arc °, lamps, laser): two poses, several lamps and cameras
# each, a laser frame and a repeated view, as a session steps through them.
SEQUENCE = [
    (cam, tt, 0.0, (lamp,), False)
    for tt in (0.0, 37.5)
    for lamp in ("lamp1", "lamp3", "lamp6")
    for cam in ("cam0", "cam2", "cam5")
] + [
    ("cam2", 37.5, 20.0, ("lamp2", "lamp7"), False),
    ("cam3", 37.5, 0.0, (), True),
    ("cam0", 0.0, 0.0, ("lamp1",), False),
]


def sequence_scene(*, noise: bool = True, **render):
    """The default scene (weave; shadows, specular, laser, noise, saturation) at 1/16;
    without ``noise``, the same scene noise-free."""
    data = tomllib.loads(DEFAULT_SCENE.read_text())
    data["render"] = {**data["render"], "scale": 0.0625, **render}
    if not noise:
        data["effects"] = [e for e in data["effects"] if e != "noise"]
        del data["noise"]
    return scene_from_dict(data)


def render_sequence(sim: Simulator) -> dict[str, np.ndarray]:
    """``image_k`` and ``signal_k`` of every frame of :data:`SEQUENCE`."""
    out = {}
    for k, (cam, tt, arc, lamps, laser) in enumerate(SEQUENCE):
        frame = sim.render_state(cam, turntable_deg=tt, arc_deg=arc, lamps_on=lamps, laser=laser)
        out[f"image_{k}"] = frame.image
        out[f"signal_{k}"] = frame.signal
    return out


if __name__ == "__main__":
    with Simulator(sequence_scene(noise="--clean" not in sys.argv)) as simulator:
        np.savez_compressed(sys.argv[1], **render_sequence(simulator))
