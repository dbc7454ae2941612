"""Small scenes for the simulator tests (64–128 px images)."""

from __future__ import annotations

from sim import scene_from_dict


def small_scene(generator: str = "bumps", *, effects=(), scale: float = 0.125, **extra):
    """A scene at 1/8 of the default camera size (128 × 96 px)."""
    data = {
        "sample": {"generator": generator, "params": extra.pop("params", {})},
        "render": {"scale": scale},
        "effects": list(effects),
        **extra,
    }
    return scene_from_dict(data)
