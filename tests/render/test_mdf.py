"""The MDF texture: its lookup on the GPU against the numpy reference, and the
rules for unseen texels and grazing views (``render.points.mdf``)."""

import moderngl
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from render.core.gl import gl_context
from render.core.programs import build_program
from render.points.mdf import GRAZING_DEG, mdf_reference, mdf_table, upload_mdf
from rig.geometry import direction_vector
from rig.material import Mdf
from tests.render.conftest import VIEWS, synthetic_mdf

_LOOKUP_FRAG = """#version 330
#include "directions.glsl"
#include "mdf.glsl"
uniform vec3 view_local;
uniform vec2 st_scale;
in vec2 v_st;
out vec4 frag;
void main() { frag = vec4(mdf_distance_mm(v_st * st_scale, view_local), 0.0, 0.0, 1.0); }
"""
_QUAD_VERT = """#version 330
in vec2 in_xy;
out vec2 v_st;
void main() { v_st = in_xy * 0.5 + 0.5; gl_Position = vec4(in_xy, 0.0, 1.0); }
"""


def gpu_lookup(table, view_local, *, method, size=48, st_scale=(1.3, 0.8)) -> np.ndarray:
    """(size, size) D from ``mdf_distance_mm`` over st ∈ [0, st_scale) on a full-screen quad."""
    ctx = gl_context()
    mdf = upload_mdf(ctx, table, view_method=method)
    program = build_program(ctx, _QUAD_VERT, _LOOKUP_FRAG, defines=mdf.defines())
    quad = ctx.buffer(np.array([-1, -1, 1, -1, -1, 1, 1, 1], np.float32))
    vao = ctx.vertex_array(program, [(quad, "2f", "in_xy")])
    colour = ctx.renderbuffer((size, size), 4, dtype="f4")
    fbo = ctx.framebuffer([colour])
    try:
        program["view_local"].value = tuple(view_local)
        program["st_scale"].value = st_scale
        program["mdf_distance"].value = 0
        program["mdf_view_cells"].value = 1
        mdf.distance.use(location=0)
        mdf.view_cells.use(location=1)
        fbo.use()
        ctx.disable(moderngl.DEPTH_TEST)
        vao.render(moderngl.TRIANGLE_STRIP)
        pixels = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32)
        return pixels.reshape(size, size, 4)[..., 0]
    finally:
        for obj in (fbo, colour, vao, quad, program):
            obj.release()
        mdf.release()


@pytest.mark.parametrize("method", ["nearest4", "barycentric", "nearest"])
@pytest.mark.parametrize(
    "view_deg", [(0.0, 0.0), (23.0, 41.0), (64.0, 137.0), (88.0, 301.0), tuple(VIEWS[12])]
)
def test_gpu_lookup_matches_reference(method, view_deg):
    table = mdf_table(synthetic_mdf(unseen=0.2))
    view = direction_vector(*view_deg)
    image = gpu_lookup(table, view, method=method)
    size = image.shape[0]
    centres = (np.arange(size) + 0.5) / size
    s, t = np.meshgrid(centres * 1.3, centres * 0.8)  # row i of the read-back is t = centre i
    expected = mdf_reference(
        table, np.column_stack([s.ravel(), t.ravel()]), np.tile(view, (s.size, 1)), method=method
    ).reshape(size, size)
    # GL's bilinear weights carry 8 bits of sub-texel precision: 1/256 of a texel step.
    step = np.abs(np.diff(table.distance_mm, axis=1)).max()
    np.testing.assert_allclose(image, expected, atol=step / 256 + 1e-5, rtol=1e-5)


def test_below_the_horizon_reads_the_horizon():
    table = mdf_table(synthetic_mdf())
    below = gpu_lookup(table, direction_vector(100.0, 30.0), method="nearest4")
    horizon = gpu_lookup(table, direction_vector(90.0, 30.0), method="nearest4")
    np.testing.assert_allclose(below, horizon, rtol=1e-6)


def test_unseen_texel_takes_the_depth_the_nearest_seeing_view_found():
    mdf = synthetic_mdf()
    distance = mdf.distance_mm.copy()
    views = direction_vector(VIEWS[:, 0], VIEWS[:, 1])
    v = 12
    angles = np.degrees(np.arccos(np.clip(views @ views[v], -1, 1)))
    nearest, second = np.argsort(angles)[1:3]
    distance[v, 3, 4] = distance[nearest, 3, 4] = -1.0  # the nearest did not see it either
    distance[second, 3, 4] = 1.0  # depth 1.0 · cos θ below the plane
    table = mdf_table(Mdf(distance, mdf.view_dirs_deg, mdf.reason, mdf.count))
    depth = 1.0 * views[second, 2]
    assert table.distance_mm[v, 3, 4] == pytest.approx(depth / views[v, 2], rel=1e-6)
    assert table.filled == 2
    assert table.never_seen == 0


def test_all_unseen_mdf_is_the_mesh_surface():
    mdf = synthetic_mdf(unseen=1.0)
    table = mdf_table(mdf)
    assert table.depth_mm == 0.0
    assert table.never_seen == table.size**2
    assert np.all(table.distance_mm == 0.0)


def test_texel_seen_by_no_view_takes_the_base_depth():
    mdf = synthetic_mdf()
    distance = mdf.distance_mm.copy()
    distance[:, 5, 6] = -1.0
    table = mdf_table(Mdf(distance, mdf.view_dirs_deg, mdf.reason, mdf.count))
    cos_theta = direction_vector(VIEWS[:, 0], VIEWS[:, 1])[:, 2]
    np.testing.assert_allclose(table.distance_mm[:, 5, 6], table.depth_mm / cos_theta, rtol=1e-6)
    assert table.never_seen == 1


def test_grazing_slot_is_clamped_and_finite():
    n = 8
    views = np.array([[0.0, 0.0], [45.0, 0.0], [89.9, 90.0], [90.0, 180.0]], np.float32)
    cos_theta = direction_vector(views[:, 0], views[:, 1])[:, 2]
    depth = np.full((n, n), 1.5)
    with np.errstate(divide="ignore"):
        distance = np.where(cos_theta[:, None, None] > 1e-6, depth / cos_theta[:, None, None], -1.0)
    shape = distance.shape
    mdf = Mdf(
        distance.astype(np.float32), views, np.zeros(shape, np.uint8), np.ones(shape, np.uint8)
    )
    table = mdf_table(mdf)
    cap = 1.5 / np.cos(np.radians(GRAZING_DEG))
    assert np.all(np.isfinite(table.distance_mm))
    np.testing.assert_allclose(table.distance_mm[2:], cap, rtol=1e-5)
    np.testing.assert_allclose(table.distance_mm[1], 1.5 / cos_theta[1], rtol=1e-5)


@given(
    views=arrays(np.float64, (5, 2), elements=st.floats(0.0, 90.0)),
    depth=arrays(np.float64, (5, 4, 4), elements=st.floats(0.0, 50.0)),
    unseen=arrays(np.bool_, (5, 4, 4)),
)
def test_any_mdf_becomes_finite_bounded_and_keeps_what_was_seen(views, depth, unseen):
    # Distinct directions: θ strictly increasing up to 90°, φ spread.
    views[:, 0] = np.sort(views[:, 0]) * 88.0 / 90.0 + np.arange(5) * 0.5
    views[:, 1] = np.arange(5) * 72.0
    cos_theta = direction_vector(views[:, 0], views[:, 1])[:, 2]
    grazing = cos_theta[:, None, None] < 1e-3
    with np.errstate(divide="ignore"):
        distance = np.where(unseen | grazing, -1.0, depth / cos_theta[:, None, None])
    distance = distance.astype(np.float32)
    shape = distance.shape
    flags = np.zeros(shape, np.uint8), np.ones(shape, np.uint8)
    table = mdf_table(Mdf(distance, views.astype(np.float32), *flags))
    cap = table.depth_mm / np.cos(np.radians(GRAZING_DEG))
    assert np.all(np.isfinite(table.distance_mm))
    assert np.all(table.distance_mm >= 0)
    assert np.all(table.distance_mm <= cap * (1 + 1e-5) + 1e-6)
    kept = (distance >= 0) & (views[:, 0] <= GRAZING_DEG)[:, None, None]
    np.testing.assert_allclose(table.distance_mm[kept], distance[kept], rtol=1e-5, atol=1e-6)
