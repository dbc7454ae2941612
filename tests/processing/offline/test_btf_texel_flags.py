"""The btf stage's per-texel flags: texels touching clipped pixels, dim lamps."""

from __future__ import annotations

from collections import Counter
from types import SimpleNamespace

import numpy as np

from processing.offline.btf import _clipped_texels, _slot_record, _texel_flags
from processing.registration import Reason
from processing.registration._homography import PlaneHomography
from rig.config import RigConfig
from rig.material import Radiometry

SIZE = 8


def _registration(config: RigConfig) -> SimpleNamespace:
    """The sample square on 4 pixels per texel of a (64, 64) frame, axis-aligned."""
    px_per_mm = 4 * SIZE / config.holder.sample_mm
    H = np.array([[px_per_mm, 0.0, 32.0 - 0.5], [0.0, -px_per_mm, 32.0 - 0.5], [0.0, 0.0, 1.0]])
    empty = np.zeros(0, np.int64)
    homography = PlaneHomography(H, np.linalg.inv(H), True, Reason.OK, empty, np.zeros(0),
                                 0.0, 0.0, empty)  # fmt: skip
    return SimpleNamespace(homography=homography)


def test_texels_touching_a_clipped_pixel_are_counted():
    config = RigConfig()
    camera = config.camera_arc.cameras[0]
    full = 2**camera.bit_depth - 1
    frame = np.full((64, 64, 3), full // 2, np.uint16 if camera.bit_depth > 8 else np.uint8)
    reg = _registration(config)
    assert _clipped_texels(frame, reg, config, camera.id, None, SIZE, "box") == 0
    frame[21, 21, 1] = full  # one pixel, one channel: the texel over it (and a box's neighbours)
    area = _clipped_texels(frame, reg, config, camera.id, None, SIZE, "area")
    box = _clipped_texels(frame, reg, config, camera.id, None, SIZE, "box")
    assert area == 1 and 1 <= box <= 4
    frame[:, :32] = full
    assert _clipped_texels(frame, reg, config, camera.id, None, SIZE, "area") == SIZE * SIZE // 2


def test_the_slot_record_says_why_no_lamp_was_placed():
    record = _slot_record(Radiometry(), None)
    assert "no near lamp placed" in record.skipped["irradiance"]
    assert "irradiance" not in record.sources


def test_the_flag_notes_count_each_flag_and_leave_out_what_none_has():
    notes = _texel_flags(Counter({"saturated": 0, "irradiance lamp3": 5, "irradiance lamp6": 0}))
    assert list(notes) == ["irradiance lamp3"]
    assert notes["irradiance lamp3"].startswith("5 texel captures it barely lights")
