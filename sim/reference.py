"""Interreflection from a physically based reference renderer (Mitsuba 3).

The ``interreflection`` effect adds the *indirect* light — light that bounced
more than once — to the explicit direct shading: Mitsuba's path tracer renders
the same mesh, camera and lamps twice with the same seed, once with
``max_depth`` and once with direct light only (``max_depth = 2``), and the
difference is added. Albedo enters Mitsuba per vertex (the texture sampled at
the mesh vertices; the plate at its mean albedo): an approximation that only
affects the indirect term. Variant ``scalar_rgb``; optional dependency
(``pip install btfrig[reference]``).
"""

from __future__ import annotations

import numpy as np

from rig.kinematics import rotate_z
from sim.holder import MARKER_BLACK, PLATE_WHITE
from sim.model import SceneModel
from sim.scene import InterreflectionParams
from sim.world import WorldSnapshot

__all__ = ["MitsubaReference", "require_mitsuba"]


def require_mitsuba():
    """Import Mitsuba 3 with the ``scalar_rgb`` variant, or explain how to get it."""
    try:
        import mitsuba as mi
    except ImportError as err:
        raise ImportError(
            "the 'interreflection' effect needs Mitsuba 3: pip install 'btfrig[reference]' "
            "(or drop 'interreflection' from the scene's effects)"
        ) from err
    mi.set_variant("scalar_rgb")
    return mi


class MitsubaReference:
    """Indirect radiance images of a scene, rendered by Mitsuba 3."""

    def __init__(self, model: SceneModel, params: InterreflectionParams):
        self._mi = require_mitsuba()
        self._model = model
        self._params = params
        mi = self._mi
        import drjit as dr

        mesh = model.mesh
        albedo = self._vertex_albedo()
        shape = mi.Mesh("scene", len(mesh.vertices), len(mesh.faces), has_vertex_normals=True)
        p = mi.traverse(shape)
        p["vertex_positions"] = dr.scalar.ArrayXf(mesh.vertices.astype(np.float32).ravel())
        p["vertex_normals"] = dr.scalar.ArrayXf(mesh.normals.astype(np.float32).ravel())
        p["faces"] = dr.scalar.ArrayXu(mesh.faces.astype(np.uint32).ravel())
        p.update()
        shape.add_attribute("vertex_color", 3, dr.scalar.ArrayXf(albedo.astype(np.float32).ravel()))
        self._shape = shape

    def _vertex_albedo(self) -> np.ndarray:
        mesh = self._model.mesh
        # Each vertex takes the material of (one of) its faces.
        material = np.zeros(len(mesh.vertices), dtype=np.int64)
        material[mesh.faces.ravel()] = np.repeat(mesh.face_material, 3)
        albedo = self._model.albedo(mesh.vertices, material)
        plate = material == 0
        area = self._model.scene.rig.holder.marker_mm**2 * len(
            self._model.scene.rig.holder.marker_centers_mm()
        )
        total = self._model.scene.rig.holder.plate_mm**2 - self._model.sample_mm**2
        mean = PLATE_WHITE + (MARKER_BLACK - PLATE_WHITE) * 0.5 * area / total
        albedo[plate] = mean
        return albedo

    def _scene(self, camera_id: str, snapshot: WorldSnapshot, max_depth: int):
        mi = self._mi
        model = self._model
        camera = model.camera(camera_id)
        tt = snapshot.turntable_deg
        eye = rotate_z(camera.center, -tt)
        forward = rotate_z(camera.R[2], -tt)
        up = rotate_z(-camera.R[1], -tt)
        fov = np.degrees(2 * np.arctan(camera.height / 2 / camera.K[1, 1]))
        emitters = {}
        for k, (_, light) in enumerate(model.lights(snapshot).items()):
            # Mitsuba measures distance in scene units (mm); our radiometry in m.
            value = light.intensity_w_sr * 1e6
            emitters[f"lamp{k}"] = {
                "type": "point",
                "position": light.position.tolist(),
                "intensity": {"type": "rgb", "value": [value] * 3},
            }
        return mi.load_dict(
            {
                "type": "scene",
                "integrator": {"type": "path", "max_depth": max_depth},
                "sensor": {
                    "type": "perspective",
                    "fov_axis": "y",
                    "fov": float(fov),
                    "to_world": mi.ScalarTransform4f().look_at(
                        origin=eye.tolist(), target=(eye + forward).tolist(), up=up.tolist()
                    ),
                    "film": {
                        "type": "hdrfilm",
                        "width": camera.width,
                        "height": camera.height,
                        "rfilter": {"type": "box"},
                        "pixel_format": "rgb",
                    },
                    "sampler": {
                        "type": "independent",
                        "sample_count": self._params.samples_per_pixel,
                    },
                },
                "shape": self._shape_dict(),
                **emitters,
            }
        )

    def _shape_dict(self):
        self._shape.set_bsdf(
            self._mi.load_dict(
                {
                    "type": "diffuse",
                    "reflectance": {"type": "mesh_attribute", "name": "vertex_color"},
                }
            )
        )
        return self._shape

    def indirect(self, camera_id: str, snapshot: WorldSnapshot) -> np.ndarray:
        """(H, W, 3) float64 indirect radiance, W/(sr·m²), clipped at 0."""
        mi = self._mi
        if not snapshot.lamps_on:
            camera = self._model.camera(camera_id)
            return np.zeros((camera.height, camera.width, 3))
        full = mi.render(self._scene(camera_id, snapshot, self._params.max_depth), seed=1)
        direct = mi.render(self._scene(camera_id, snapshot, 2), seed=1)
        return np.clip(np.array(full, dtype=np.float64) - np.array(direct), 0, None)
