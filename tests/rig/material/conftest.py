"""Small synthetic materials, and archives that hold them."""

import dataclasses

import numpy as np
import pytest

from rig.archive import Archive, FrameFormat
from rig.material import (
    CompressedBTF,
    GlobalSVD,
    Mdf,
    PbrFlag,
    PbrMaps,
    PsView,
    write_btf,
    write_mdf,
    write_pbr,
    write_ps,
)

N = 8
SAMPLE_MM = 60.0
VIEWS = np.array([[0.0, 0.0], [30.0, 90.0], [60.0, 180.0]])
LIGHTS = np.array([[0.0, 0.0], [45.0, 0.0], [45.0, 120.0], [45.0, 240.0]])
RIG = {"holder": {"plate_mm": 120.0, "sample_mm": SAMPLE_MM, "marker_mm": 10.0}}
CALIBRATION = {
    "cameras": {"cam0": {"rms_px": 0.2}},
    "cameras_provenance": {"archive": "charuco.zarr", "at": "2026-01-02T03:04:05"},
}


def pca_model(seed: int = 0, c: int = 2) -> CompressedBTF:
    rng = np.random.default_rng(seed)
    v, n_l = len(VIEWS), len(LIGHTS)
    return CompressedBTF(
        VIEWS, LIGHTS,
        rng.uniform(0, 1, (v, N, N, 3)).astype(np.float16),
        rng.uniform(-1, 1, (v, c, N, N, 3)).astype(np.float16),
        rng.normal(0, 0.1, (v, n_l, c)).astype(np.float32),
        rng.uniform(0, 1, (v, n_l)).astype(np.float32),
        np.full(v, c, np.int32),
    )  # fmt: skip


def svd_model(seed: int = 1, c: int = 2) -> GlobalSVD:
    rng = np.random.default_rng(seed)
    return GlobalSVD(
        VIEWS, LIGHTS,
        rng.uniform(-1, 1, (c, len(LIGHTS), N, N, 3)).astype(np.float16),
        rng.normal(0, 1, (len(VIEWS), c)).astype(np.float32),
        rng.uniform(0, 1, len(VIEWS)).astype(np.float32),
        c,
    )  # fmt: skip


def ps_view(name: str, view_deg=(0.0, 0.0), seed: int = 2) -> PsView:
    rng = np.random.default_rng(seed)
    normals = rng.normal(0, 0.2, (N, N, 3)) + np.array([0.0, 0.0, 1.0])
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    valid = rng.uniform(size=(N, N)) > 0.2
    return PsView(
        name,
        normals.astype(np.float32),
        rng.uniform(0, 1, (N, N, 3)).astype(np.float32),
        valid,
        np.where(valid, 0, 3).astype(np.uint8),
        rng.normal(0, 0.1, (N, N)).astype(np.float32),
        view_deg=view_deg,
        attrs={"camera": "cam0", "turntable_deg": 0.0, "steps": [1, 2, 3]},
    )


def mdf(seed: int = 3) -> Mdf:
    rng = np.random.default_rng(seed)
    distance = rng.uniform(0, 2, (2, N, N)).astype(np.float32)
    distance[:, 0, :3] = -1.0
    return Mdf(
        distance,
        np.array([[0.0, 0.0], [30.0, 45.0]], np.float32),
        np.where(distance < 0, 2, 0).astype(np.uint8),
        np.where(distance < 0, 0, 3).astype(np.uint8),
        attrs={"peak": "gaussian", "views": ["cam0_tt000.0", "cam1_tt000.0"]},
    )


def make_archive(path, **groups):
    """An archive (no frames) whose material has the given groups, written by the writers."""
    writers = {
        "btf": lambda g, m: write_btf(g, m, units="relative radiance", slot_valid=None),
        "ps": lambda g, views: write_ps(g, views, attrs={"method": "irls"}),
        "mdf": write_mdf,
        "pbr": write_pbr,
    }
    with Archive.create(
        path, plan={}, rig_config=RIG, cameras={"cam0": FrameFormat(4, 4, 1, "uint8")},
        calibration=CALIBRATION, fsync=False,
    ) as archive:  # fmt: skip
        for name, value in groups.items():
            with archive.replace_material(name) as group:
                writers[name](group, value)
    return path


@pytest.fixture
def archive(tmp_path):
    """An archive with a PCA BTF, two PS views and an MDF."""
    views = [ps_view("cam1_tt000.0", (30.0, 0.0), 4), ps_view("cam0_tt000.0", (2.0, 0.0))]
    return make_archive(tmp_path / "s.zarr", btf=pca_model(), ps=views, mdf=mdf())


def pbr_maps(n=4, channels=3, **changes) -> PbrMaps:
    """Fitted PBR maps of n² texels with random values in range; ``changes`` replace fields."""
    rng = np.random.default_rng(0)
    normal = np.dstack([rng.normal(0, 0.1, (n, n, 2)), np.ones((n, n))])
    maps = PbrMaps(
        base_colour=rng.uniform(0, 1, (n, n, channels)), roughness=rng.uniform(0, 1, (n, n)),
        specular=rng.uniform(0, 1, (n, n)), specular_colour=rng.uniform(0, 5, (n, n)),
        sheen_colour=rng.uniform(0, 1, (n, n, channels)), sheen_roughness=np.full((n, n), 0.5),
        anisotropy=np.zeros((n, n)), anisotropy_deg=np.full((n, n), 30.0),
        normal=normal / np.linalg.norm(normal, axis=-1, keepdims=True),
        height_mm=rng.normal(0, 0.1, (n, n)), error_rmse=np.full((n, n), 0.01),
        flags=np.full((n, n), PbrFlag.NO_SPECULAR, np.uint8), attrs={"psnr_db": 31.5},
    )  # fmt: skip
    return dataclasses.replace(maps, **changes)
