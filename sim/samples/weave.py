"""A plain weave of yarns: the non-height-field sample.

Warp yarns run along y, weft yarns along x, both at ``pitch_mm``; warp *i*
passes over weft *j* where ``i + j`` is even. Each yarn is a tube of
elliptical cross-section (``width_mm`` × ``thickness_mm``) around a sinusoidal
centre line, so yarns overhang each other and the recess floor shows through
the gaps: a surface seen from above is not a height field, and the MDF sees
the difference (seed ``001_…``, §4).
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from rig.errors import ConfigError
from sim.samples.base import SampleGeometry, register_sample

__all__ = ["WeaveParams"]


class WeaveParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    pitch_mm: float = Field(4.0, gt=0, description="distance between neighbouring yarns")
    width_mm: float = Field(2.6, gt=0, description="yarn width (< pitch leaves gaps)")
    thickness_mm: float = Field(1.0, gt=0, description="yarn thickness")
    crimp_mm: float = Field(0.6, ge=0, description="amplitude of the over/under undulation")
    segments: int = Field(12, ge=3, le=64, description="mesh segments around a yarn")
    steps_per_pitch: int = Field(8, ge=2, le=64, description="mesh steps along a yarn")


def _yarn(axis: int, offset: float, sign: float, p: WeaveParams, s_mm: float, z0: float):
    """Vertices, exact normals and faces of one yarn along ``axis`` (0 = x, 1 = y)."""
    m = max(2, round(s_mm / p.pitch_mm * p.steps_per_pitch) + 1)
    k = p.segments
    rx, rz = p.width_mm / 2, p.thickness_mm / 2
    first = -s_mm / 2 + p.pitch_mm / 2

    def surface(t, phi_shift=0.0):
        zc = z0 + sign * p.crimp_mm * np.cos(np.pi * (t - first) / p.pitch_mm)
        dz = -sign * p.crimp_mm * np.pi / p.pitch_mm * np.sin(np.pi * (t - first) / p.pitch_mm)
        centre = np.zeros((len(t), 3))
        centre[:, axis] = t
        centre[:, 1 - axis] = offset
        centre[:, 2] = zc
        tangent = np.zeros((len(t), 3))
        tangent[:, axis] = 1.0
        tangent[:, 2] = dz
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        b = np.zeros((len(t), 3))
        b[:, 1 - axis] = 1.0 if axis == 1 else -1.0  # b × tangent points up
        n = np.cross(b, tangent)
        phi = np.linspace(0, 2 * np.pi, k, endpoint=False) + phi_shift
        return centre, (
            centre[:, None, :]
            + rx * np.cos(phi)[None, :, None] * b[:, None, :]
            + rz * np.sin(phi)[None, :, None] * n[:, None, :]
        )

    t = np.linspace(-s_mm / 2, s_mm / 2, m)
    centre, pts = surface(t)
    # Exact normals: cross product of the parametric derivatives (central differences).
    eps = 1e-5
    d_s = (surface(t + eps)[1] - surface(t - eps)[1]) / (2 * eps)
    d_phi = (surface(t, eps)[1] - surface(t, -eps)[1]) / (2 * eps)
    normals = np.cross(d_s, d_phi)
    normals /= np.linalg.norm(normals, axis=2, keepdims=True)
    outward = np.einsum("mkc,mkc->mk", normals, pts - centre[:, None, :]) > 0
    normals = np.where(outward[..., None], normals, -normals)
    idx = np.arange(m * k).reshape(m, k)
    a, b = idx[:-1], np.roll(idx[:-1], -1, axis=1)
    c, d = np.roll(idx[1:], -1, axis=1), idx[1:]
    faces = np.concatenate(
        [np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]
    )
    return pts.reshape(-1, 3), normals.reshape(-1, 3), faces


@register_sample("weave", WeaveParams, n_materials=2)
def _weave(params: WeaveParams, *, sample_mm: float, depth_mm: float) -> SampleGeometry:
    half = params.crimp_mm + params.thickness_mm / 2
    if 2 * half > depth_mm:
        raise ConfigError(
            f"sample.depth_mm: the weave is {2 * half:.3f} mm thick (2·crimp + thickness) "
            f"but the recess is only {depth_mm} mm deep; deepen it or thin the yarns"
        )
    n = int(np.floor(sample_mm / params.pitch_mm + 1e-9))
    if n < 2:
        raise ConfigError(
            f"sample.params.pitch_mm: {params.pitch_mm} mm leaves fewer than 2 yarns on a "
            f"{sample_mm} mm sample"
        )
    z0 = -half  # the crests of the upper yarns touch the reference plane
    centres = -sample_mm / 2 + (np.arange(n) + 0.5) * params.pitch_mm
    verts, norms, faces, mats = [], [], [], []
    count = 0
    for axis, material in ((1, 0), (0, 1)):  # warp along y, then weft along x
        for i, offset in enumerate(centres):
            # Warp i is up at weft j when i + j is even; weft is the opposite.
            sign = (1.0 if i % 2 == 0 else -1.0) * (1.0 if axis == 1 else -1.0)
            v, nrm, f = _yarn(axis, offset, sign, params, sample_mm, z0)
            verts.append(v)
            norms.append(nrm)
            faces.append(f + count)
            mats.append(np.full(len(f), material))
            count += len(v)
    return SampleGeometry(
        vertices=np.concatenate(verts),
        faces=np.concatenate(faces).astype(np.int64),
        normals=np.concatenate(norms),
        face_material=np.concatenate(mats).astype(np.int64),
        height=None,
    )
