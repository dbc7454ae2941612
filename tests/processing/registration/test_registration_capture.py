"""register_capture: a frame as the archive holds it (rig config + step record)."""

from __future__ import annotations

import numpy as np
import pytest

from processing.registration import RegistrationError, register_capture, register_frame
from rig.archive import StepRecord


def test_capture_registers_like_the_frame_with_the_config_camera(frames, rig_config):
    frame, _, _ = frames("cam3", 30.0)
    step = StepRecord(7, "btf", ("cam3",), {"cam3": (45.0, 330.0)}, (15.0, 90.0),
                      {"turntable_deg": 30.0})  # fmt: skip
    out = register_capture(frame, rig_config, step, "cam3", size=16)
    direct = register_frame(frame, rig_config.holder, size=16,
                            camera=rig_config.camera_model("cam3"))  # fmt: skip
    assert out.registration.valid and out.step == 7 and out.camera == "cam3"
    np.testing.assert_array_equal(out.registration.normtexture.texture,
                                  direct.normtexture.texture)  # fmt: skip
    np.testing.assert_allclose(out.view_deg, [45.0, 330.0])
    np.testing.assert_allclose(out.light_deg, [15.0, 90.0])


def test_capture_names_a_wrong_camera(rig_config):
    step = StepRecord(3, "btf", ("cam3",), {"cam3": (45.0, 0.0)}, (0.0, 0.0))
    blank = np.zeros((64, 64), np.uint8)
    with pytest.raises(RegistrationError, match="'cam5' did not capture step 3"):
        register_capture(blank, rig_config, step, "cam5", size=8)
    odd = StepRecord(4, "btf", ("camX",), {"camX": (45.0, 0.0)}, (0.0, 0.0))
    with pytest.raises(RegistrationError, match="not in the rig config"):
        register_capture(blank, rig_config, odd, "camX", size=8)
