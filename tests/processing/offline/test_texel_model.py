"""Each texel's capture moved to the nominal directions by the fitted reflectance model
(``processing.offline.texel_model``): exact where the model is the texel's reflectance."""

import numpy as np
import pytest

from processing.offline.texel_model import (
    MAX_RATIO,
    ModelMove,
    model_params,
    model_record,
    moved_by_model,
)
from processing.offline.texel_resample import texel_directions
from rig.geometry import direction_vector
from rig.material import PbrMaps, PbrParams, Radiometry, evaluate_pbr

SAMPLE_MM, N = 100.0, 8
#: the coarse plan's lights, and lamps 650 mm away along them
LIGHTS = np.array([*[[15, p] for p in (0, 120, 240)], *[[45, p] for p in (0, 90, 180, 270)]],
                  float)  # fmt: skip
LAMPS = [650.0 * direction_vector(t, p) for t, p in LIGHTS]
VIEW_DEG = (45.0, 30.0)
CAMERA = 800.0 * direction_vector(*VIEW_DEG)


def _params(roughness: float = 0.35) -> PbrParams:
    """N² texels of a glossy, tilted, anisotropic material, every texel different."""
    rng = np.random.default_rng(3)
    t = N * N
    normal = np.column_stack([rng.uniform(-0.3, 0.3, (t, 2)), np.ones(t)])
    return PbrParams(
        base_colour=rng.uniform(0.2, 0.8, (t, 3)), roughness=np.full(t, roughness),
        specular=np.full(t, 1.0), specular_colour=np.full(t, 1.0),
        sheen_colour=np.zeros((t, 3)), sheen_roughness=np.full(t, 0.5),
        anisotropy=rng.uniform(0, 0.5, t), anisotropy_deg=rng.uniform(0, 180, t),
        normal=normal / np.linalg.norm(normal, axis=1, keepdims=True),
    )  # fmt: skip


def _own_lights() -> np.ndarray:
    return np.stack([texel_directions(lamp, SAMPLE_MM, N) for lamp in LAMPS])  # (L, N, N, 3)


def _captured(params: PbrParams, own_lights, own_view) -> np.ndarray:
    """(L, N, N, 3) what the btf stage stores for a texel of reflectance ``params`` lit
    from its own lamp directions and seen from its own: the model's value there, its
    irradiance divided out on the reference plane (× cos θ_centre / cos θ_t)."""
    lights = np.moveaxis(own_lights.reshape(len(LAMPS), N * N, 3), 0, 1)
    views = np.broadcast_to(own_view.reshape(N * N, 1, 3), lights.shape)
    values = evaluate_pbr(params, lights, views)  # (T, L, C)
    centre_z = np.array([lamp[2] / np.linalg.norm(lamp) for lamp in LAMPS])
    values = values * (centre_z[None, :] / lights[..., 2])[..., None]
    return np.moveaxis(values, 1, 0).reshape(len(LAMPS), N, N, 3).astype(np.float32)


def _truth(params: PbrParams) -> np.ndarray:
    nominal = direction_vector(LIGHTS[:, 0], LIGHTS[:, 1])
    view = np.broadcast_to(direction_vector(*VIEW_DEG), nominal.shape)
    return np.moveaxis(evaluate_pbr(params, nominal, view), 1, 0).reshape(len(LAMPS), N, N, 3)


def test_per_texel_directions_evaluate_as_each_texel_alone():
    params = _params()
    rng = np.random.default_rng(5)
    light = rng.normal(size=(N * N, 4, 3)) + np.array([0.0, 0.0, 3.0])
    light /= np.linalg.norm(light, axis=-1, keepdims=True)
    view = np.broadcast_to(direction_vector(*VIEW_DEG), light.shape)
    together = evaluate_pbr(params, light, view)
    alone = [evaluate_pbr(params.map(lambda a, t=t: a[t : t + 1]), light[t], view[t])[0]
             for t in range(N * N)]  # fmt: skip
    np.testing.assert_allclose(together, np.stack(alone), rtol=1e-12)


def test_a_capture_moved_by_its_own_model_lands_on_the_nominal_value():
    params = _params()
    own_lights, own_view = _own_lights(), texel_directions(CAMERA, SAMPLE_MM, N)
    captured = _captured(params, own_lights, own_view)
    truth = _truth(params)
    centre_z = np.array([lamp[2] / np.linalg.norm(lamp) for lamp in LAMPS])
    moved, record = moved_by_model(
        captured, params, light_deg=LIGHTS, view_deg=VIEW_DEG, own_lights=own_lights,
        centre_z=centre_z, own_view=own_view,
    )  # fmt: skip
    raw = np.abs(captured - truth) / truth.max()
    error = np.abs(moved - truth) / truth.max()
    assert raw.max() > 0.02  # the lamps' and camera's turn moves a glossy texel's value
    assert error.max() < 1e-5  # to float32
    assert moved.dtype == np.float32 and np.isfinite(moved).all()
    assert record == ModelMove(0, len(LIGHTS) * N * N, record.largest)
    assert 1.0 < record.largest < MAX_RATIO


def test_only_the_light_moved_keeps_the_view_as_captured():
    params = _params()
    own_lights = _own_lights()
    frontal = np.broadcast_to(direction_vector(*VIEW_DEG), (N, N, 3))
    captured = _captured(params, own_lights, frontal)
    centre_z = np.array([lamp[2] / np.linalg.norm(lamp) for lamp in LAMPS])
    moved, _ = moved_by_model(captured, params, light_deg=LIGHTS, view_deg=VIEW_DEG,
                              own_lights=own_lights, centre_z=centre_z, own_view=None)  # fmt: skip
    np.testing.assert_allclose(moved, _truth(params), atol=1e-5 * _truth(params).max())


def test_a_texel_the_model_calls_dark_or_a_wild_ratio_is_kept_as_measured():
    params = _params(roughness=0.03)  # a mirror: the lobe moves by far more than 2×
    dark = params.map(np.copy)
    dark.normal[0] = [0.0, -0.999, 0.045]  # lit from behind its horizon by every lamp
    own_lights, own_view = _own_lights(), texel_directions(CAMERA, SAMPLE_MM, N)
    captured = np.ones((len(LIGHTS), N, N, 3), np.float32)
    centre_z = np.array([lamp[2] / np.linalg.norm(lamp) for lamp in LAMPS])
    moved, record = moved_by_model(captured, dark, light_deg=LIGHTS, view_deg=VIEW_DEG,
                                   own_lights=own_lights, centre_z=centre_z,
                                   own_view=own_view)  # fmt: skip
    assert (moved[:, 0, 0] == 1.0).all()  # the dark texel, untouched
    assert 0 < record.kept < record.captures
    assert np.isfinite(moved).all() and moved.max() <= MAX_RATIO * 1.2


def test_maps_become_one_row_per_texel():
    params = _params()
    grid = {name: getattr(params, name).reshape(N, N, *getattr(params, name).shape[1:])
            for name in ("base_colour", "roughness", "specular", "specular_colour",
                         "sheen_colour", "sheen_roughness", "anisotropy", "anisotropy_deg",
                         "normal")}  # fmt: skip
    maps = PbrMaps(**grid, height_mm=np.zeros((N, N)), error_rmse=np.zeros((N, N)),
                   flags=np.zeros((N, N), np.uint8))  # fmt: skip
    again = model_params(maps)
    for name in grid:
        np.testing.assert_array_equal(getattr(again, name), getattr(params, name), err_msg=name)


@pytest.mark.parametrize(
    ("slots", "source", "skipped"),
    [
        ([ModelMove(0, 100, 1.2), ModelMove(3, 100, 1.5)], "factors up to 1.500",
         "3 of 200 texel captures kept as measured"),
        ([ModelMove(0, 100, 1.2), "no fitted PBR model"], "factors up to 1.200",
         "no fitted PBR model: 1 of 2 view slots kept"),
        (["no fitted PBR model", "no fitted PBR model"], None,
         "no fitted PBR model: every slot kept"),
    ],
)  # fmt: skip
def test_the_record_says_what_was_moved_and_what_kept(slots, source, skipped):
    record = model_record(Radiometry(), slots, lights="model", views="nominal")
    if source is None:
        assert "model" not in record.sources
    else:
        assert record.sources["model"].startswith("lights moved by the fitted PBR model")
        assert source in record.sources["model"]
    assert skipped in record.skipped["model"]
