"""The renderer: a measured material on any mesh under point and directional lights.

``Renderer(material, mesh).render(camera, lights)`` gives a linear float
image; ``EnvironmentRenderer(material, mesh).render(camera, environment)`` lights
it with an HDR environment map instead; :mod:`render.output` writes it as an
sRGB PNG or a float EXR. Headless through EGL (Mesa's llvmpipe without a
GPU). See ``docs/render.md``.
"""

from render._errors import RenderError
from render.camera import Camera
from render.env_renderer import EnvironmentRenderer
from render.environment import EnvironmentMap, read_environment, synthetic_environment
from render.lights import MAX_LIGHTS, DirectionalLight, Light, PointLight
from render.renderer import Renderer

__all__ = [
    "MAX_LIGHTS",
    "Camera",
    "DirectionalLight",
    "EnvironmentMap",
    "EnvironmentRenderer",
    "Light",
    "PointLight",
    "RenderError",
    "Renderer",
    "read_environment",
    "synthetic_environment",
]
