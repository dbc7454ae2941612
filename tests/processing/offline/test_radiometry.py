"""The flat field's geometry: a map measured with arc and turntable at 0° serves a step
at any arc and turntable angle, and the linearisation looks values up per channel."""

import numpy as np
import pytest

from processing.offline.radiometry import FrameCorrections, _texel_points, point_falloff
from rig.config import default_rig_config
from rig.kinematics import lamp_position_mm


def _irradiance(source, points):
    to_lamp = source - points
    return to_lamp[..., 2] / np.linalg.norm(to_lamp, axis=-1) ** 3


@pytest.mark.parametrize(("arc", "turntable"), [(0.0, 0.0), (90.0, 0.0), (30.0, 200.0)])
def test_turned_texels_see_the_lamp_as_the_map_saw_it(arc, turntable):
    config = default_rig_config()
    lamp, z = "lamp3", -0.5
    points = _texel_points(100.0, 8, z, arc_deg=arc, turntable_deg=turntable)
    # the lamp where it stands for this step, in the sample frame, on the texels as they lie
    source = lamp_position_mm(config, lamp, arc_deg=arc, turntable_deg=turntable)
    xy = _texel_points(100.0, 8, z, arc_deg=0.0, turntable_deg=0.0)
    direct = _irradiance(source, xy) / _irradiance(source, np.array([0.0, 0.0, z]))
    np.testing.assert_allclose(point_falloff(config, lamp, points, z), direct, rtol=1e-12)
    if (arc, turntable) != (0.0, 0.0):  # the turn matters: the fall-off is not symmetric
        assert not np.allclose(point_falloff(config, lamp, xy, z), direct, rtol=1e-3)


def test_linearisation_looks_up_each_channel():
    curve = np.stack([np.arange(256), 2 * np.arange(256), 3 * np.arange(256)], -1) / 128.0
    corrections = FrameCorrections(curves={"cam0": curve.astype(np.float32)})
    frame = np.array([[[128, 64, 255]]], np.uint8)
    np.testing.assert_allclose(corrections.linear(frame, "cam0"), [[[1.0, 1.0, 255 * 3 / 128]]])
    assert corrections.linear(frame, "cam1") is None
    assert corrections.linear(frame.astype(np.uint16), "cam0") is None
