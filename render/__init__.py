"""The renderer: a measured material on any mesh under point and directional lights.

``Renderer(material, mesh).render(camera, lights)`` gives a linear float
image; :mod:`render.output` writes it as an sRGB PNG or a float EXR. Headless
through EGL (Mesa's llvmpipe without a GPU). See ``docs/render.md``.
"""

from render._errors import RenderError
from render.camera import Camera
from render.lights import MAX_LIGHTS, DirectionalLight, Light, PointLight
from render.renderer import Renderer

__all__ = [
    "MAX_LIGHTS",
    "Camera",
    "DirectionalLight",
    "Light",
    "PointLight",
    "RenderError",
    "Renderer",
]
