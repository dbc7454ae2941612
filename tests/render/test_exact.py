"""The GPU renderer against the CPU reference, texel by texel.

A quad seen orthographically from +z with one pixel per texel, its shading
frame turned so the camera sees it from a chosen direction in the sample
frame (``conftest.tilted_quad``): every pixel must equal
``processing.btf.interpolate`` at that view and light direction, measured or
not, for both kinds of BTF and every blending method; PS shading must equal a
numpy Lambert of the same maps.

Tolerance: the GPU reads the same float16 texels the CPU does but sums in
float32 (the CPU in float64) and computes the blend weights in float32. The
difference allowed is 2⁻¹¹ (float16's relative precision, half a unit in the
last place of the stored texels) of the largest texel of the reference: the
float32 sums stay hundreds of times below it, while a wrong neighbour or
weight (the nearest-direction blend instead, say) misses it 30–260 times.
"""

import numpy as np
import pytest

from processing.btf import compress_btf, interpolate
from render import Camera, DirectionalLight, PointLight, Renderer
from render.texel_view import texel_camera
from rig.geometry import direction_angles, direction_vector, texel_centers_mm
from tests.render.conftest import LIGHTS, SAMPLE_MM, VIEWS, N, material, ps_view, tilted_quad

FLOAT16_EPS = 2.0**-11

CASES = {
    "measured frontal": ((0.0, 0.0), (0.0, 0.0)),
    "measured oblique": (tuple(VIEWS[7]), tuple(LIGHTS[20])),
    "unmeasured": ((23.0, 41.0), (47.0, 200.0)),
    "unmeasured steep": ((64.0, 137.0), (78.0, 301.0)),
    "measured view, unmeasured light": (tuple(VIEWS[12]), (12.5, 93.0)),
}


def frontal_camera() -> Camera:
    return texel_camera(SAMPLE_MM, N)


def render_at(model_material, view_deg, light_deg, **options) -> np.ndarray:
    mesh, frame = tilted_quad(view_deg)
    light = DirectionalLight(tuple(frame @ direction_vector(*light_deg)))
    with Renderer(model_material, mesh, shadows=False, **options) as renderer:
        return renderer.render(frontal_camera(), [light])


@pytest.mark.parametrize("kind", ["pca", "svd"])
@pytest.mark.parametrize("method", ["nearest4", "barycentric", "nearest"])
@pytest.mark.parametrize("case", CASES)
def test_btf_matches_cpu_interpolation(kind, method, case, request):
    model = request.getfixturevalue(f"{kind}_model")
    view_deg, light_deg = CASES[case]
    image = render_at(material(model), view_deg, light_deg, light_method=method, view_method=method)
    expected = interpolate(
        model, view_deg=view_deg, light_deg=light_deg, light_method=method, view_method=method
    )
    tolerance = FLOAT16_EPS * np.abs(expected).max()
    np.testing.assert_allclose(image, expected, atol=tolerance, rtol=0)


def numpy_ps_shading(ps, view_local, light_local, *, specular, shininess) -> np.ndarray:
    """albedo · max(0, n·l) + specular · max(0, n·h)^shininess where n·l > 0 and l_z > 0."""
    n = ps.normals.astype(np.float64)
    cos_in = n @ light_local
    half = (light_local + view_local) / np.linalg.norm(light_local + view_local)
    lobe = specular * np.clip(n @ half, 0.0, None) ** shininess
    lit = (cos_in > 0) & (light_local[2] > 0)
    return np.where(lit[..., None], ps.albedo * cos_in[..., None] + lobe[..., None], 0.0)


@pytest.mark.parametrize(
    ("view_deg", "light_deg"), [((0.0, 0.0), (30.0, 45.0)), ((41.0, 250.0), (63.0, 17.0))]
)
def test_ps_shading_matches_numpy_lambert(view_deg, light_deg):
    ps = ps_view()
    image = render_at(material(ps=ps), view_deg, light_deg, specular=0.3, shininess=20.0)
    expected = numpy_ps_shading(
        ps, direction_vector(*view_deg), direction_vector(*light_deg), specular=0.3, shininess=20.0
    )
    assert (expected > 0.05).mean() > 0.5  # most texels lit: the comparison means something
    np.testing.assert_allclose(image, expected, atol=1e-5, rtol=1e-4)


def test_grey_btf_shades_all_three_channels_alike(synthetic_btf):
    """A one-channel material (C = 1) renders grey: each channel equals the CPU's value."""
    grey = np.asarray(synthetic_btf)[..., 1:2]
    model = compress_btf(grey, view_dirs_deg=VIEWS, light_dirs_deg=LIGHTS, components=4)
    image = render_at(material(model), (23.0, 41.0), (47.0, 200.0))
    expected = interpolate(model, view_deg=(23.0, 41.0), light_deg=(47.0, 200.0))
    assert expected.shape == (N, N, 1)
    np.testing.assert_allclose(image, np.repeat(expected, 3, axis=2),
                               atol=FLOAT16_EPS * np.abs(expected).max())  # fmt: skip


@pytest.mark.parametrize("kind", ["pca", "svd"])
def test_every_pixel_its_own_directions_under_perspective_and_a_lamp(kind, request):
    """A camera on the quad's axis sees the fronto-parallel quad as a scaled copy, so pixels
    still land on texel centres, but each pixel has its own view direction, and a lamp 60 mm
    away its own light direction and 1/r²: each texel against the CPU at its own directions."""
    model = request.getfixturevalue(f"{kind}_model")
    mesh, frame = tilted_quad((30.0, 40.0))
    distance = 60.0
    camera = Camera.perspective(
        (0, 0, distance),
        (0, 0, 0),
        up=(0, 1, 0),
        size=(N, N),
        fov_deg=2 * np.rad2deg(np.arctan(SAMPLE_MM / 2 / distance)),
    )
    lamp = np.array([25.0, -10.0, 60.0])
    with Renderer(material(model), mesh, shadows=False) as renderer:
        image = renderer.render(camera, [PointLight(tuple(lamp), intensity=5000.0)])
    expected = np.zeros_like(image)
    centres = texel_centers_mm(SAMPLE_MM, N)
    for r in range(N):
        for c in range(N):
            p = np.array([*centres[r, c], 0.0])
            to_lamp = lamp - p
            view = direction_angles(frame.T @ (camera.eye - p))
            light = direction_angles(frame.T @ to_lamp)
            texture = interpolate(model, view_deg=np.ravel(view), light_deg=np.ravel(light))
            expected[r, c] = 5000.0 / np.dot(to_lamp, to_lamp) * texture[r, c]
    np.testing.assert_allclose(image, expected, atol=FLOAT16_EPS * np.abs(expected).max())
