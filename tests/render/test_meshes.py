"""Meshes: tangent frames against analytic ones, hard cases, the draped cloth, files."""

import numpy as np
import pytest
import trimesh
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from numpy.testing import assert_allclose
from scipy.signal import find_peaks

from render._cloth import drape
from render.meshes import (
    BUILT_IN,
    Mesh,
    MeshError,
    cloth,
    cylinder,
    load_mesh,
    mesh_by_name,
    mesh_from_arrays,
    plane,
    sphere,
    torus,
)


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    cos = np.sum(a * b, axis=1) / np.linalg.norm(a, axis=1) / np.linalg.norm(b, axis=1)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def _assert_orthonormal(mesh: Mesh) -> None:
    tangent, normal = mesh.tangents[:, :3].astype(float), mesh.normals.astype(float)
    assert np.isfinite(mesh.tangents).all()
    assert_allclose(np.linalg.norm(tangent, axis=1), 1.0, atol=1e-5)
    assert_allclose(np.linalg.norm(normal, axis=1), 1.0, atol=1e-5)
    assert_allclose(np.sum(tangent * normal, axis=1), 0.0, atol=1e-5)
    assert set(np.unique(mesh.tangents[:, 3])) <= {-1.0, 1.0}


def _east(positions: np.ndarray) -> np.ndarray:
    """The analytic tangent along +u of every shape whose u runs around the z axis."""
    phi = np.arctan2(positions[:, 1], positions[:, 0])
    return np.stack([-np.sin(phi), np.cos(phi), np.zeros_like(phi)], axis=1)


@pytest.mark.parametrize("name", ["plane", "sphere", "cylinder", "torus", "cloth"])
def test_built_in_frames_are_orthonormal_and_right_handed(name):
    mesh = mesh_by_name(name)
    assert mesh.name == name
    _assert_orthonormal(mesh)
    assert mesh.degenerate_faces == 0
    assert mesh.fallback_frames == 0
    # Every built-in is parametrised with +v = normal × (+u): no mirrored UVs.
    assert (mesh.tangents[:, 3] == 1.0).all()


def test_plane_frame_and_uvs_in_mm():
    mesh = plane(size_mm=80.0, segments=4)
    assert_allclose(mesh.tangents, np.tile([1.0, 0.0, 0.0, 1.0], (len(mesh.uvs), 1)), atol=1e-6)
    assert_allclose(mesh.normals, np.tile([0.0, 0.0, 1.0], (len(mesh.uvs), 1)))
    # One UV unit is one mm of surface.
    assert_allclose(mesh.uvs, mesh.positions[:, :2] + 40.0, atol=1e-5)


def test_sphere_tangents_follow_the_parallels():
    mesh = sphere(radius_mm=50.0, segments=48)
    positions = mesh.positions.astype(float)
    assert_allclose(np.linalg.norm(positions, axis=1), 50.0, rtol=1e-6)
    assert_allclose(mesh.normals, positions / 50.0, atol=1e-6)
    # The poles are singular in a latitude–longitude map: left out.
    away_from_poles = np.abs(positions[:, 2]) < 50.0 * np.sin(np.radians(80.0))
    error = _angle_deg(mesh.tangents[away_from_poles, :3], _east(positions[away_from_poles]))
    assert error.max() < 0.25
    # The date line is a seam: its copies get both sides' triangles, so they share one
    # frame and are as good as any other meridian (one-sided, they tilt by half a segment, 1.9°).
    seam = away_from_poles & (np.abs(positions[:, 1]) < 1e-4) & (positions[:, 0] > 0)
    assert seam.sum() > 2 * 30
    assert _angle_deg(mesh.tangents[seam, :3], _east(positions[seam])).max() < 0.25
    by_height = np.lexsort((positions[seam, 1], positions[seam, 2]))
    copies = mesh.tangents[seam][by_height].reshape(-1, 2, 4)
    assert_allclose(copies[:, 0], copies[:, 1], atol=1e-6)


@pytest.mark.parametrize("build", [cylinder, torus])
def test_cylinder_and_torus_tangents_agree_with_analytic(build):
    mesh = build()
    positions = mesh.positions.astype(float)
    assert _angle_deg(mesh.tangents[:, :3], _east(positions)).max() < 0.05
    bitangent = mesh.tangents[:, 3:] * np.cross(mesh.normals, mesh.tangents[:, :3])
    # +v runs up the cylinder and around the torus's tube from the outer equator upward.
    outer_equator = np.abs(positions[:, 2]) < 1e-3
    outer_equator &= np.hypot(positions[:, 0], positions[:, 1]) >= np.median(
        np.hypot(positions[:, 0], positions[:, 1])
    )
    assert_allclose(
        bitangent[outer_equator], np.tile([0, 0, 1.0], (outer_equator.sum(), 1)), atol=1e-3
    )


def test_mirrored_uvs_flip_the_handedness():
    flat = plane(size_mm=10.0, segments=2)
    mirrored = mesh_from_arrays(
        flat.positions, flat.uvs * [-1.0, 1.0], flat.faces, name="mirrored", normals=flat.normals
    )
    assert_allclose(
        mirrored.tangents[:, :3], np.tile([-1.0, 0.0, 0.0], (len(flat.uvs), 1)), atol=1e-6
    )
    assert (mirrored.tangents[:, 3] == -1.0).all()
    # The bitangent w·(n × t) still runs along +v, which is +y.
    bitangent = mirrored.tangents[:, 3:] * np.cross(mirrored.normals, mirrored.tangents[:, :3])
    assert_allclose(bitangent, np.tile([0.0, 1.0, 0.0], (len(flat.uvs), 1)), atol=1e-6)


def test_mirror_seam_keeps_each_side_its_own_frame():
    """Two halves sharing an edge, the right one with u mirrored (a symmetric garment's UVs)."""
    positions = np.array(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [2, 0, 0], [2, 1, 0]],
        float,
    )
    uvs = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [1, 0], [1, 1], [0, 0], [0, 1]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 6, 7], [4, 7, 5]])
    mesh = mesh_from_arrays(positions, uvs, faces, name="mirror seam")
    assert_allclose(mesh.tangents[:4], np.tile([1.0, 0, 0, 1.0], (4, 1)), atol=1e-6)
    assert_allclose(mesh.tangents[4:], np.tile([-1.0, 0, 0, -1.0], (4, 1)), atol=1e-6)


def test_degenerate_triangles_and_zero_area_uvs_give_finite_counted_frames():
    positions = np.array(
        [
            [0, 0, 0],
            [1, 0, 0],
            [0, 1, 0],
            [5, 5, 0],
            [5, 5, 0],
            [5, 5, 0],
            [2, 0, 0],
            [3, 0, 0],
            [2, 1, 0],
        ],
        float,
    )
    uvs = np.array(
        [[0, 0], [1, 0], [0, 1], [0, 0], [1, 0], [0, 1], [0.5, 0.5], [0.5, 0.5], [0.5, 0.5]]
    )
    # A good triangle, one collapsed to a point, one with all three UVs equal.
    faces = np.array([[0, 1, 2], [3, 4, 5], [6, 7, 8]])
    mesh = mesh_from_arrays(positions, uvs, faces, name="hard cases")
    _assert_orthonormal(mesh)
    assert mesh.degenerate_faces == 2
    assert mesh.fallback_frames == 6
    assert_allclose(mesh.tangents[:3, :3], np.tile([1.0, 0, 0], (3, 1)), atol=1e-6)


_coordinates = st.floats(-10.0, 10.0, allow_nan=False, width=32)


@given(
    positions=arrays(np.float64, (6, 3), elements=_coordinates),
    uvs=arrays(np.float64, (6, 2), elements=_coordinates),
    faces=arrays(np.int64, (5, 3), elements=st.integers(0, 5)),
)
def test_any_triangles_give_finite_orthonormal_frames(positions, uvs, faces):
    mesh = mesh_from_arrays(positions, uvs, faces, name="random")
    _assert_orthonormal(mesh)
    assert 0 <= mesh.degenerate_faces <= len(faces)


@pytest.fixture(scope="module")
def draped():
    return cloth()


def test_cloth_rests_on_the_sphere_and_the_table(draped):
    positions = draped.positions.astype(float)
    assert 2000 <= len(positions) <= 5000
    assert np.linalg.norm(positions, axis=1).min() >= 80.0 - 1e-3
    assert positions[:, 2].min() >= -80.0 - 1e-3
    # It lies on the sphere's top, not above it.
    assert positions[:, 2].max() == pytest.approx(80.0, abs=1.0)


def test_cloth_hangs_in_folds(draped):
    """Around the sphere below its equator, the skirt's distance from the axis rises and falls:
    more ridges than the square's four corners would make."""
    positions = draped.positions.astype(float)
    band = (positions[:, 2] > -55.0) & (positions[:, 2] < -25.0)
    azimuth = np.arctan2(positions[band, 1], positions[band, 0])
    reach = np.hypot(positions[band, 0], positions[band, 1])
    bins = np.floor((azimuth + np.pi) / (2 * np.pi) * 72).astype(int) % 72
    profile = np.array([reach[bins == b].max() for b in range(72)])
    peaks, _ = find_peaks(np.concatenate([profile, profile]), prominence=10.0)
    ridges = np.unique(peaks % 72)
    assert len(ridges) >= 6


def test_cloth_uvs_keep_the_rest_lengths(draped):
    """Every edge of the grid is within 10 % of its UV length, 95 % within 3 %."""
    faces = draped.faces.astype(int)
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    uv_length = np.linalg.norm(np.diff(draped.uvs[edges].astype(float), axis=1)[:, 0], axis=1)
    length = np.linalg.norm(np.diff(draped.positions[edges].astype(float), axis=1)[:, 0], axis=1)
    grid_edges = np.isclose(uv_length, uv_length.min(), rtol=1e-3)
    stretch = length[grid_edges] / uv_length[grid_edges]
    assert np.abs(stretch - 1.0).max() < 0.10
    assert np.percentile(np.abs(stretch - 1.0), 95) < 0.03


def test_drape_is_deterministic():
    first = drape(size_mm=100.0, sphere_radius_mm=30.0, segments=8, settle_s=0.2)
    second = drape(size_mm=100.0, sphere_radius_mm=30.0, segments=8, settle_s=0.2)
    assert np.array_equal(first, second)
    assert first[:, 2].max() < 30.0 + 100.0 / 8  # it fell


def _plane_file(path):
    """A 100 mm plane with UVs in [0, 1], as a modelling tool would write it: in mm,
    +Z up, or as glTF defines, in metres with +Y up."""
    flat = plane(size_mm=100.0, segments=4)
    visual = trimesh.visual.TextureVisuals(uv=flat.uvs / 100.0)
    x, y, z = flat.positions.T
    positions = np.stack([x, z, -y], axis=1) / 1000.0 if path.suffix in (".glb", ".gltf") else None
    mesh = trimesh.Trimesh(
        flat.positions if positions is None else positions, flat.faces, visual=visual,
        process=False,
    )  # fmt: skip
    if path.suffix == ".gltf":
        # A .gltf comes with its buffers; trimesh hands them back as named files.
        for name, content in mesh.export(file_type="gltf").items():
            (path.parent / (path.name if name == "model.gltf" else name)).write_bytes(content)
    else:
        mesh.export(path)
    return flat


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".glb", ".gltf"])
def test_load_mesh_reads_uvs_and_scales_them_to_mm(tmp_path, suffix):
    path = tmp_path / f"quad{suffix}"
    flat = _plane_file(path)
    mesh = load_mesh(path)
    assert mesh.name == str(path)
    assert len(mesh.faces) == len(flat.faces)
    order = np.lexsort(mesh.positions.T)
    expected = np.lexsort(flat.positions.T)
    assert_allclose(mesh.positions[order], flat.positions[expected], atol=1e-5)
    assert_allclose(mesh.uvs[order], flat.uvs[expected], atol=1e-3)
    assert_allclose(mesh.tangents[order], flat.tangents[expected], atol=1e-5)
    assert_allclose(mesh.normals, [[0, 0, 1]] * len(mesh.normals), atol=1e-6)
    assert mesh_by_name(path).positions.shape == mesh.positions.shape


def test_load_mesh_in_metres(tmp_path):
    path = tmp_path / "quad.obj"
    _plane_file(path)
    mesh = load_mesh(path, mm_per_unit=1000.0)
    assert np.ptp(mesh.positions[:, 0]) == pytest.approx(100_000.0)
    assert np.ptp(mesh.uvs[:, 0]) == pytest.approx(100_000.0, rel=1e-5)


def test_stl_has_no_uvs_and_the_error_names_the_file(tmp_path):
    path = tmp_path / "statue.stl"
    trimesh.creation.box(extents=(10, 10, 10)).export(path)
    with pytest.raises(MeshError, match=r"statue\.stl.*no texture coordinates"):
        load_mesh(path)


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("missing.obj", None, "no such mesh file"),
        ("garbage.glb", b"not a mesh at all", "cannot read the mesh"),
        ("model.fbx", b"", r"unknown mesh format '\.fbx'.*\.obj"),
    ],
)
def test_bad_files_are_named(tmp_path, name, content, message):
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(MeshError, match=message) as caught:
        load_mesh(path)
    assert str(path) in str(caught.value)


def test_unknown_name_lists_the_built_ins():
    with pytest.raises(MeshError, match="cushion") as caught:
        mesh_by_name("cushion")
    assert all(name in str(caught.value) for name in BUILT_IN)


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: sphere(radius_mm=-1.0), "radius_mm is -1.0"),
        (lambda: torus(major_mm=10.0, minor_mm=20.0), "minor_mm 20.0 must be smaller"),
        (lambda: cylinder(segments=2), "segments is 2"),
    ],
)
def test_bad_sizes_are_named(build, message):
    with pytest.raises(MeshError, match=message):
        build()


def test_mesh_checks_its_arrays():
    flat = plane()
    fields = {f: getattr(flat, f) for f in ("positions", "normals", "uvs", "tangents", "faces")}
    with pytest.raises(MeshError, match=r"uvs has shape \(4, 3\); expected \(N, 2\)"):
        Mesh(**{**fields, "uvs": np.zeros((4, 3))}, name="bad")
    with pytest.raises(MeshError, match="normals holds NaN"):
        Mesh(**{**fields, "normals": np.full((4, 3), np.nan)}, name="bad")
    with pytest.raises(MeshError, match="faces refer to vertex 9"):
        Mesh(**{**fields, "faces": np.array([[0, 1, 9]])}, name="bad")
    assert not flat.positions.flags.writeable
