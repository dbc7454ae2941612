"""The mirror sphere of the lamp calibration, as a sample.

Its parameters are the rig's own target spec (:class:`rig.targets.MirrorSphere`),
so the simulator renders the ball that lamp calibration measures with: a
sphere resting on the reference plane, its centre at ``centre_mm(0)`` in the
sample frame. It rises above the plate (z up to 2r), which a sample may not
but a target may; seen from below the reference plane (the texel truth, the
MDF) it is invisible and the recess floor shows.

The mesh is an icosphere whose vertex normals are exact (radial). Interpolated
across a facet they stay radial — ``Σ bᵢ vᵢ / r`` is the hit point's own
direction from the centre — so the shading is a sphere's; only the facet's
sagitta (``e² / 8r`` for edge length e, 0.8 µm at the default 6 subdivisions
and r = 25 mm) moves the silhouette and the highlight.
"""

from __future__ import annotations

import numpy as np
import trimesh

from rig.targets import MirrorSphere
from sim.samples.base import SampleGeometry, register_sample

__all__ = ["SUBDIVISIONS"]

SUBDIVISIONS = 6  # 81 920 faces


@register_sample("mirror_sphere", MirrorSphere)
def _mirror_sphere(sphere: MirrorSphere, *, sample_mm: float, depth_mm: float) -> SampleGeometry:
    ball = trimesh.creation.icosphere(subdivisions=SUBDIVISIONS, radius=sphere.radius_mm)
    unit = np.asarray(ball.vertices, dtype=np.float64) / sphere.radius_mm
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    faces = np.asarray(ball.faces, dtype=np.int64)
    return SampleGeometry(
        vertices=sphere.centre_mm(0.0) + sphere.radius_mm * unit,
        faces=faces,
        normals=unit,
        face_material=np.zeros(len(faces), dtype=np.int64),
    )
