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
from render.texel_view import texel_quad
from rig.geometry import Sampling, direction_vector
from rig.material import Material, Mdf, PsView, write_btf

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


def tilted_quad(view_deg) -> tuple[Mesh, np.ndarray]:
    """The SAMPLE_MM quad seen from ``view_deg`` by a camera on +z (``render.texel_view``):
    the mesh and the local → world rotation F."""
    return texel_quad(SAMPLE_MM, view_deg)


def synthetic_mdf(n: int = 12, seed: int = 0, unseen: float = 0.0) -> Mdf:
    """Random depths below the plane seen from VIEWS (D = h / cos θ); a fraction unseen."""
    rng = np.random.default_rng(seed)
    depth = rng.uniform(0.0, 2.0, (n, n))
    cos_theta = direction_vector(VIEWS[:, 0], VIEWS[:, 1])[:, 2]
    distance = np.broadcast_to(depth, (len(VIEWS), n, n)) / cos_theta[:, None, None]
    distance = np.where(rng.random(distance.shape) < unseen, -1.0, distance)
    shape = distance.shape
    return Mdf(
        distance.astype(np.float32), VIEWS.astype(np.float32),
        np.zeros(shape, np.uint8), np.ones(shape, np.uint8),
    )  # fmt: skip
