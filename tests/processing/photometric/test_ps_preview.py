"""Preview images: dtype, shape and the mapping of a few known values."""

import numpy as np

from processing.photometric import albedo_preview, hillshade_preview, normal_map_preview


def test_normal_map_maps_minus_one_to_zero_and_up_to_blue():
    normals = np.zeros((2, 2, 3))
    normals[..., 2] = 1.0
    normals[1, 1] = [-1.0, 0.0, 0.0]
    image = normal_map_preview(normals)
    assert image.dtype == np.uint8 and image.shape == (2, 2, 3)
    assert image[0, 0].tolist() == [128, 128, 255] and image[1, 1].tolist() == [0, 128, 128]


def test_albedo_preview_white_point_and_invalid_black():
    albedo = np.linspace(0, 2, 100).reshape(10, 10)
    valid = np.ones((10, 10), bool)
    valid[0, 1] = False
    image = albedo_preview(albedo, valid=valid, white_percentile=100, gamma=1.0)
    assert image.max() == 255 and image[0, 1] == 0
    assert abs(int(image[5, 0]) - round(255 * albedo[5, 0] / 2)) <= 1
    assert albedo_preview(np.zeros((3, 3, 3))).shape == (3, 3, 3)


def test_hillshade_lights_the_slope_facing_the_lamp():
    x = np.arange(20) * 0.1
    ramp_up_x = np.tile(x, (20, 1))  # rises towards +x: faces -x
    shade_from_minus_x = hillshade_preview(ramp_up_x, pitch_mm=0.1, azimuth_deg=180)
    shade_from_plus_x = hillshade_preview(ramp_up_x, pitch_mm=0.1, azimuth_deg=0)
    assert shade_from_minus_x.mean() > shade_from_plus_x.mean()
    assert hillshade_preview(np.zeros((1, 1)), pitch_mm=1.0).dtype == np.uint8
