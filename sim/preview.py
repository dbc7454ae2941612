"""PNGs a person can look at: what the rig's cameras see, and the truth maps.

``rig sim render SCENE --out DIR`` calls :func:`write_preview`.
"""

from __future__ import annotations

import logging
from pathlib import Path

import cv2
import numpy as np

from sim.scene import Scene, load_scene
from sim.simulator import Frame, Simulator

__all__ = ["frame_to_png8", "write_preview"]

log = logging.getLogger(__name__)


def frame_to_png8(frame: Frame) -> np.ndarray:
    """An 8-bit BGR (or grey) image of a frame for viewing."""
    img = frame.image.astype(np.float64) * (255.0 / (2**frame.bit_depth - 1))
    img = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    return img[..., ::-1] if img.ndim == 3 else img


def _pick(ids: list[str], count: int) -> list[str]:
    if len(ids) <= count:
        return ids
    return [ids[i] for i in np.linspace(0, len(ids) - 1, count).round().astype(int)]


def write_preview(
    scene: Scene | str | Path,
    out_dir: str | Path,
    *,
    cameras: int = 3,
    lamps: int = 2,
    turntable_deg: float = 30.0,
    arc_deg: float = 60.0,
    texels: int = 256,
) -> list[Path]:
    """Render a few cameras × lamps, a laser frame and the truth maps as PNGs.

    Writes ``<camera>_<lamp>.png`` for ``cameras`` cameras and ``lamps`` lamps
    spread over the rig, ``<camera>_laser.png`` (laser on, lamps off) for the
    first camera, and ``truth_normals.png`` (normals as RGB = (n + 1) / 2),
    ``truth_height.png`` (black = lowest, white = z = 0), ``truth_albedo.png``
    on the ``texels``² grid (seen from above, row 0 at +y).

    Returns
    -------
    list of Path, the files written
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []

    def save(name: str, image: np.ndarray) -> None:
        path = out / name
        if not cv2.imwrite(str(path), image):
            raise OSError(f"cannot write {path}")
        written.append(path)

    with Simulator(scene if isinstance(scene, Scene) else load_scene(scene)) as sim:
        rig = sim.scene.rig
        cam_ids = _pick([c.id for c in rig.camera_arc.cameras], cameras)
        lamp_ids = _pick([lamp.id for lamp in rig.lamps], lamps)
        for cam in cam_ids:
            for lamp in lamp_ids:
                frame = sim.render_state(
                    cam, turntable_deg=turntable_deg, arc_deg=arc_deg, lamps_on=[lamp]
                )
                save(f"{cam}_{lamp}.png", frame_to_png8(frame))
        if sim.scene.has("laser"):
            frame = sim.render_state(
                cam_ids[0], turntable_deg=turntable_deg, arc_deg=arc_deg, laser=True
            )
            save(f"{cam_ids[0]}_laser.png", frame_to_png8(frame))
        truth = sim.texel_truth(texels)
    normals = np.clip((truth.normals + 1) / 2 * 255, 0, 255).astype(np.uint8)
    save("truth_normals.png", normals[..., ::-1])
    h = truth.height
    span = max(float(h.max() - h.min()), 1e-9)
    save("truth_height.png", np.rint((h - h.min()) / span * 255).astype(np.uint8))
    albedo = np.clip(truth.albedo * 255, 0, 255).astype(np.uint8)
    save("truth_albedo.png", albedo[..., ::-1])
    log.info("wrote %d preview images to %s", len(written), out)
    return written
