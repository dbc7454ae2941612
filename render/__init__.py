"""The renderer: a measured material on any mesh under point and directional lights.

``Renderer(material, mesh).render(camera, lights)`` gives a linear float
image; ``EnvironmentRenderer(material, mesh).render(camera, environment)`` lights
it with an HDR environment map instead, ``PemRenderer(material, mesh).render_environment(
camera, environment)`` by partial environment maps; :mod:`render.output` writes it as an
sRGB PNG or a float EXR. Headless through EGL (Mesa's llvmpipe without a
GPU). See ``docs/render.md``.

The families live in subpackages (:mod:`render.points`, :mod:`render.environment`,
:mod:`render.pem`) over the GPU parts they share (:mod:`render.core`); the scene they
draw (:mod:`render.camera`, :mod:`render.lights`, :mod:`render.meshes`) and the image
files and window (:mod:`render.output`, :mod:`render.window`) are modules of this package.
"""

from render._errors import RenderError
from render.camera import Camera
from render.core.programs import shader_source
from render.environment import (
    EnvironmentMap,
    EnvironmentRenderer,
    read_environment,
    synthetic_environment,
)
from render.lights import MAX_LIGHTS, DirectionalLight, Light, PointLight
from render.pem import PemRenderer
from render.points import Renderer

__all__ = [
    "MAX_LIGHTS",
    "Camera",
    "DirectionalLight",
    "EnvironmentMap",
    "EnvironmentRenderer",
    "Light",
    "PemRenderer",
    "PointLight",
    "RenderError",
    "Renderer",
    "read_environment",
    "shader_source",
    "synthetic_environment",
]
