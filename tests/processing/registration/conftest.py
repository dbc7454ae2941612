"""Fixtures of the registration tests: the rig config and cached synthetic frames."""

from __future__ import annotations

import numpy as np
import pytest

from rig.camera import PinholeCamera
from rig.config import Holder, default_rig_config
from tests.processing.registration.plate_frames import camera_homography, render_plate


@pytest.fixture(scope="session")
def rig_config():
    return default_rig_config()


@pytest.fixture(scope="session")
def holder(rig_config) -> Holder:
    return rig_config.holder


@pytest.fixture(scope="session")
def frames(rig_config):
    """Rendered frames by (camera id, turntable deg), cached for the session."""
    cache: dict[tuple[str, float], tuple[np.ndarray, np.ndarray, PinholeCamera]] = {}

    def get(camera_id: str, turntable_deg: float):
        key = (camera_id, turntable_deg)
        if key not in cache:
            camera = rig_config.camera_model(camera_id)
            G = camera_homography(camera, turntable_deg)
            frame = render_plate(rig_config.holder, G, camera.width, camera.height)
            cache[key] = (frame, G, camera)
        return cache[key]

    return get
