"""Small measured-like materials and an exact-texel scene for the renderer's tests.

Every image is at most 256² and the BTFs are 16 × 16 texels, so the folder
runs in well under two minutes on llvmpipe.
"""

from pathlib import Path

import numpy as np
import pytest
import zarr

from processing.btf import compress_btf, compress_global_svd
from processing.btf.synthetic import SyntheticBTF
from render.meshes import Mesh
from rig.geometry import Sampling, direction_vector
from rig.material import Material, PsView, write_btf

SAMPLE_MM = 20.0
N = 16
#: View slots: every third direction of H2 (27 slots over the hemisphere).
VIEWS = Sampling.named("H2").directions[::3]
LIGHTS = Sampling.named("H1").directions


@pytest.fixture(scope="session")
def synthetic_btf():
    return SyntheticBTF(N, VIEWS, LIGHTS, sample_mm=SAMPLE_MM)


@pytest.fixture(scope="session")
def pca_model(synthetic_btf):
    return compress_btf(synthetic_btf, view_dirs_deg=VIEWS, light_dirs_deg=LIGHTS, components=6)


@pytest.fixture(scope="session")
def svd_model(synthetic_btf):
    return compress_global_svd(
        synthetic_btf, view_dirs_deg=VIEWS, light_dirs_deg=LIGHTS, components=6
    )


@pytest.fixture(scope="session")
def store(tmp_path_factory, pca_model):
    """A standalone material store holding a 16 × 16 per-view PCA BTF."""
    path = tmp_path_factory.mktemp("view") / "m.zarr"
    root = zarr.open_group(path, mode="w", zarr_format=3)
    root.attrs.update(
        format="btfrig.material", version=1, sample_mm=SAMPLE_MM, size=16, provenance={}
    )
    write_btf(root.create_group("btf"), pca_model, units="relative radiance")
    return path


def material(btf=None, *, slot_valid=None, ps=None) -> Material:
    """A Material in memory (what rig.material.read_material returns)."""
    if btf is not None and slot_valid is None:
        slot_valid = np.ones(len(btf.view_dirs_deg), bool)
    return Material(
        source=Path("test-material"), sample_mm=SAMPLE_MM, size=N, btf=btf,
        btf_slot_valid=slot_valid, ps={} if ps is None else {ps.name: ps},
    )  # fmt: skip


def ps_view(n: int = N, seed: int = 0) -> PsView:
    """Bumpy unit normals and a coloured albedo on an n × n grid."""
    rng = np.random.default_rng(seed)
    slope = 0.6 * rng.standard_normal((n, n, 2))
    normals = np.dstack([-slope, np.ones((n, n))])
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    albedo = rng.uniform(0.1, 0.9, (n, n, 3))
    return PsView(
        name="cam0", normals=normals.astype(np.float32), albedo=albedo.astype(np.float32),
        valid=np.ones((n, n), bool), reason=np.zeros((n, n), np.uint8),
        height_mm=np.zeros((n, n), np.float32), view_deg=(0.0, 0.0),
    )  # fmt: skip


def _rotation_to_z(v: np.ndarray) -> np.ndarray:
    """The rotation F with F @ v = +z (Rodrigues about v × z)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(v, z)
    s, c = np.linalg.norm(axis), float(np.dot(v, z))
    if s < 1e-12:
        return np.eye(3)
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


def tilted_quad(view_deg) -> tuple[Mesh, np.ndarray]:
    """The sample-sized quad in z = 0, its shading frame turned so that a camera on
    +z sees it from ``view_deg`` in its tangent frame.

    Each of the N × N pixels of an orthographic camera looking down −z (up +y,
    height SAMPLE_MM) then lands on one texel centre and sees the texture from
    the same local direction. Returns the mesh and the local → world rotation F.
    """
    f = _rotation_to_z(direction_vector(*view_deg))
    s = SAMPLE_MM / 2
    positions = np.array([[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]], np.float32)
    uvs = (positions[:, :2] + s).astype(np.float32)  # mm of surface, 0…SAMPLE_MM
    normal, tangent = f @ [0.0, 0.0, 1.0], f @ [1.0, 0.0, 0.0]
    mesh = Mesh(
        positions=positions, normals=np.tile(normal, (4, 1)).astype(np.float32), uvs=uvs,
        tangents=np.tile([*tangent, 1.0], (4, 1)).astype(np.float32),
        faces=np.array([[0, 1, 2], [0, 2, 3]], np.uint32), name="tilted quad",
    )  # fmt: skip
    return mesh, f
