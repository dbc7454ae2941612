"""An interactive viewer: the headless renderer's frames shown in a pyglet window.

The renderer keeps drawing off screen (EGL); the window only shows its sRGB
frames, so the window's own GL context needs nothing beyond blitting an image.
Dragging orbits the camera (left–right about the vertical axis, up–down in
elevation); shift-dragging turns the lights about the vertical axis; the
mouse wheel changes the exposure by a third of a stop; Escape closes.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable

import numpy as np

from render._errors import RenderError
from render.output import to_srgb8

__all__ = ["open_window", "require_display"]

_DEG_PER_PIXEL = 0.4
_FRAMES_PER_S = 30.0


def require_display() -> None:
    """Raise :class:`RenderError` unless a window can open (on Linux: a named X11 or
    Wayland display)."""
    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        raise RenderError(
            "no display: --window needs an X11 or Wayland display (neither DISPLAY nor "
            "WAYLAND_DISPLAY is set); write an image with --out instead"
        )


def open_window(
    draw: Callable[[float, float, float], np.ndarray],
    *,
    size: tuple[int, int],
    exposure_ev: float = 0.0,
    title: str = "rig view",
) -> None:
    """Show ``draw(turn_deg, tilt_deg, light_turn_deg) -> (H, W, 3) linear`` until closed.

    ``turn_deg`` turns the camera about the vertical axis, ``tilt_deg`` raises
    it, ``light_turn_deg`` turns the lights; each starts at 0.

    Raises
    ------
    RenderError
        No display, or the window system refused the window.
    """
    require_display()
    import pyglet

    try:
        window = pyglet.window.Window(*size, caption=title, resizable=False)
    except Exception as err:  # pyglet's display errors have no common base class
        raise RenderError(f"the window system refused a {size[0]}×{size[1]} window: {err}") from err
    state = {"turn": 0.0, "tilt": 0.0, "light": 0.0, "exposure": exposure_ev, "dirty": True}
    shown: list = [None]

    def refresh(_elapsed: float) -> None:
        if not state["dirty"]:
            return
        state["dirty"] = False
        linear = draw(state["turn"], state["tilt"], state["light"])
        pixels = to_srgb8(linear, exposure_ev=state["exposure"])[::-1]  # pyglet: rows bottom-up
        shown[0] = pyglet.image.ImageData(size[0], size[1], "RGB", pixels.tobytes())

    @window.event
    def on_draw() -> None:
        window.clear()
        if shown[0] is not None:
            shown[0].blit(0, 0)

    @window.event
    def on_mouse_drag(x, y, dx, dy, buttons, modifiers) -> None:
        if modifiers & pyglet.window.key.MOD_SHIFT:
            state["light"] += _DEG_PER_PIXEL * dx
        else:
            state["turn"] -= _DEG_PER_PIXEL * dx
            state["tilt"] = float(np.clip(state["tilt"] + _DEG_PER_PIXEL * dy, -85.0, 85.0))
        state["dirty"] = True

    @window.event
    def on_mouse_scroll(x, y, scroll_x, scroll_y) -> None:
        state["exposure"] += scroll_y / 3.0
        state["dirty"] = True

    refresh(0.0)
    pyglet.clock.schedule_interval(refresh, 1.0 / _FRAMES_PER_S)
    try:
        pyglet.app.run()
    finally:
        pyglet.clock.unschedule(refresh)
