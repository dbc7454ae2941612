"""A scene made concrete: its mesh, materials, lamps, laser and cameras.

Shared by the rasterised image path (:mod:`sim.simulator`) and the ray-cast
ground truth (:mod:`sim.truth`); it holds no GL state.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from rig.camera import PinholeCamera
from rig.kinematics import laser_plane, laser_source_mm, rotate_z
from sim.holder import RECESS_GREY, SceneMesh, assemble, plate_albedo
from sim.kinds import sim_kind
from sim.materials import eval_albedo
from sim.raycast import RayCaster
from sim.samples import SampleGeometry, generator
from sim.scene import Scene
from sim.shading import LightSource, SurfaceHits
from sim.world import WorldSnapshot

__all__ = ["HIT_CHUNK", "SceneModel"]

#: rays whose hits are reconstructed at a time (``SceneModel.hits``)
HIT_CHUNK = 1 << 18


@dataclass
class SceneModel:
    """Geometry and appearance of a scene, sample frame (mm)."""

    scene: Scene

    @cached_property
    def sample(self) -> SampleGeometry:
        spec = self.scene.spec.sample
        return generator(spec.generator).build(
            self._recess[1], sample_mm=self.recess_mm, depth_mm=spec.depth_mm
        )

    @property
    def sample_mm(self) -> float:
        """Side of the measured square (the texel grids'), mm."""
        return self.scene.rig.holder.sample_mm

    @property
    def recess_mm(self) -> float:
        """Side of the holder's recess and of the sample filling it, mm: the measured
        square and ``sample.margin_mm`` on every side (a height field's: rounded up to whole
        steps of its lattice)."""
        return self._recess[0]

    @cached_property
    def _recess(self):
        """The recess side and the generator's parameters for it. A height field's lattice
        keeps its points on the measured square where they were without a margin (the
        square's own truth does not move) and adds whole steps around it, unless a step is
        longer than the margin (a plane's)."""
        params = self.scene.sample_params
        margin = self.scene.spec.sample.margin_mm
        grid = getattr(params, "grid", None)
        if grid is None:
            return self.sample_mm + 2.0 * margin, params
        pitch = self.sample_mm / (grid - 1)
        steps = int(np.ceil(margin / pitch - 1e-9))
        if steps * pitch <= 2.0 * margin:
            return self.sample_mm + 2 * steps * pitch, params.model_copy(
                update={"grid": grid + 2 * steps}
            )
        # A lattice coarser than the margin (a plane): no finer than it was over the square.
        recess = self.sample_mm + 2.0 * margin
        intervals = int(np.ceil((grid - 1) * recess / self.sample_mm - 1e-9))
        return recess, params.model_copy(update={"grid": intervals + 1})

    @cached_property
    def mesh(self) -> SceneMesh:
        spec = self.scene.spec.sample
        return assemble(
            self.scene.rig.holder, self.sample, depth_mm=spec.depth_mm, recess_mm=self.recess_mm
        )

    @cached_property
    def caster(self) -> RayCaster:
        return RayCaster(self.mesh)

    @cached_property
    def _plate(self):
        return plate_albedo(self.scene.rig.holder)

    @cached_property
    def specular(self) -> dict:
        """Material index → specular lobe, for the materials that have one."""
        spec = self.scene.spec
        lobes = {}
        for k, name in enumerate(spec.sample.materials):
            if spec.materials[name].specular is not None:
                lobes[2 + k] = spec.materials[name].specular
        return lobes

    def albedo(self, points: np.ndarray, materials: np.ndarray) -> np.ndarray:
        """Albedo (n, 3) of hits on materials (0 plate, 1 recess, 2 + k sample)."""
        out = np.empty((len(points), 3))
        xy = points[:, :2]
        plate = materials == 0
        out[plate] = self._plate(xy[plate])
        out[materials == 1] = RECESS_GREY
        spec = self.scene.spec
        for k, name in enumerate(spec.sample.materials):
            sel = materials == 2 + k
            if sel.any():
                out[sel] = eval_albedo(
                    spec.materials[name].albedo, xy[sel], sample_mm=self.sample_mm
                )
        # A weave given one material uses it for warp and weft alike.
        last = 2 + len(spec.sample.materials) - 1
        extra = materials > last
        if extra.any():
            name = spec.sample.materials[-1]
            out[extra] = eval_albedo(
                spec.materials[name].albedo, xy[extra], sample_mm=self.sample_mm
            )
        if self.sample.pattern is not None:
            printed = materials >= 2
            out[printed] *= self.sample.pattern(points[printed])[:, None]
        return out

    def hits(self, shape, pixels, origin, dirs, faces, *, chunk: int = HIT_CHUNK) -> SurfaceHits:
        """Exact surface hits of rays on the faces something found for them.

        ``origin`` (3,) or (n, 3) mm; ``pixels``, ``faces`` (n,), ``dirs`` (n, 3).
        Built ``chunk`` rays at a time: the temporaries (~0.4 kB a ray) stay near
        100 MB however large the (supersampled) image; the hits are the same.
        """
        parts = []
        for start in range(0, max(len(pixels), 1), chunk):
            run = slice(start, start + chunk)
            origins = origin if np.ndim(origin) == 1 else origin[run]
            parts.append(
                SurfaceHits.build(
                    self.mesh, shape, pixels[run], origins, dirs[run], faces[run], self.albedo
                )
            )
        return parts[0] if len(parts) == 1 else SurfaceHits.concatenate(parts)

    def camera(self, camera_id: str, snapshot: WorldSnapshot | None = None) -> PinholeCamera:
        """The camera's model in the sample frame (turntable at 0); in the Bonn lab,
        where ``snapshot``'s arm and rail put it."""
        rig, as_built = self.scene.rig, self.scene.as_built
        camera = sim_kind(rig.kind).camera(rig, camera_id, snapshot)
        return camera if as_built is None else as_built.camera(camera_id, camera)

    def camera_rays(self, camera: PinholeCamera, turntable_deg: float):
        """Pinhole rays through every pixel centre in the sample frame.

        Returns the origin (3,) and unit directions (H·W, 3), row-major.
        """
        # The ray through pixel (u, v) is x·a₀ + y·a₁ + a₂ with aᵢ the camera's axes
        # (rows of R) in the sample frame; built row by column, not by stacking.
        axes = rotate_z(camera.R, -turntable_deg)
        x = (np.arange(camera.width) - camera.K[0, 2]) / camera.K[0, 0]
        y = (np.arange(camera.height) - camera.K[1, 2]) / camera.K[1, 1]
        d = np.empty((camera.height, camera.width, 3))
        np.multiply(x[None, :, None], axes[0], out=d)
        d += (y[:, None] * axes[1] + axes[2])[:, None, :]
        d = d.reshape(-1, 3)
        d /= np.sqrt(np.einsum("ij,ij->i", d, d))[:, None]
        return rotate_z(camera.center, -turntable_deg), d

    def lights(self, snapshot: WorldSnapshot) -> dict[str, LightSource]:
        """The lit lamps of a snapshot, placed in the sample frame."""
        rig, as_built = self.scene.rig, self.scene.as_built
        kind = sim_kind(rig.kind)
        out = {}
        for lamp_id in sorted(snapshot.lamps_on):
            lamp = rig.lamp(lamp_id)
            pos = kind.lamp_mm(rig, lamp_id, snapshot)
            intensity = self.scene.spec.radiometry.intensity_w_sr
            if as_built is not None:  # where the lamp stands as built, how bright it is
                pos = pos + kind.mount_offset_mm(rig, as_built.lamp_offset_mm[lamp_id], snapshot)
                intensity = intensity * as_built.lamp_gain[lamp_id]
            out[lamp_id] = LightSource.from_lamp(lamp, pos, intensity)
        return out

    def laser_sheet(self, snapshot: WorldSnapshot) -> tuple[np.ndarray, np.ndarray, float]:
        """Laser source position (3,), sheet normal (3,) and offset d, sample frame."""
        rig = self.scene.rig
        source = laser_source_mm(
            rig, snapshot.laser_mount, arc_deg=snapshot.arc_deg,
            turntable_deg=snapshot.turntable_deg,
        )  # fmt: skip
        normal, d = laser_plane(
            rig,
            arc_deg=snapshot.arc_deg,
            mount=snapshot.laser_mount,
            tilt_deg=snapshot.laser_tilt_deg,
            turntable_deg=snapshot.turntable_deg,
        )
        return source, normal, d
