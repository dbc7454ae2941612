"""The process's one headless OpenGL context (EGL), its framebuffers and mesh buffers.

Creating an EGL context costs tens of milliseconds and each holds driver
threads, so the renderers of a process share one, made on first use: Mesa's
llvmpipe on a machine without a GPU, the GPU's driver where there is one.
"""

from __future__ import annotations

from functools import cache

import moderngl
import numpy as np

from render._errors import RenderError

__all__ = ["gl_context", "image_framebuffer", "mesh_buffers", "vertex_array"]

_GL_VERSION = 330
_ATTRIBUTES = (("in_position", 3), ("in_normal", 3), ("in_uv", 2), ("in_tangent", 4))


def gl_context() -> moderngl.Context:
    """The shared standalone context (EGL backend, OpenGL ≥ 3.3 core), current on this thread.

    Another EGL user of the process (the simulator's rasteriser) makes its own
    context current and unbinds it afterwards, so each call binds this one again.
    """
    ctx = _created_context()
    ctx.__enter__()
    return ctx


@cache
def _created_context() -> moderngl.Context:
    try:
        ctx = moderngl.create_context(standalone=True, backend="egl", require=_GL_VERSION)
    except Exception as err:  # moderngl raises bare Exception for EGL failures
        raise RenderError(
            f"no headless OpenGL {_GL_VERSION // 100}.{_GL_VERSION % 100 // 10} context through "
            f"EGL ({err}); install Mesa's EGL (libegl1, libgl1-mesa-dri) or a GPU driver"
        ) from err
    return ctx


def image_framebuffer(ctx: moderngl.Context, size: tuple[int, int]) -> moderngl.Framebuffer:
    """A float RGBA colour + depth framebuffer of ``size`` (width, height) pixels.

    RenderError naming the size and the GL renderer when the context cannot hold
    it: beyond its GL_MAX_RENDERBUFFER_SIZE or GL_MAX_VIEWPORT_DIMS, or refused by
    the driver (llvmpipe gives up on a float framebuffer of over 2 GiB, below
    those limits).
    """
    limits = (ctx.info["GL_MAX_RENDERBUFFER_SIZE"], *ctx.info["GL_MAX_VIEWPORT_DIMS"])
    largest = min(int(limit) for limit in limits)
    width, height = size
    refused = f"{largest}×{largest} pixels at most" if max(size) > largest else None
    if refused is None:
        buffers = []
        try:
            buffers.append(ctx.renderbuffer(size, 4, dtype="f4"))
            buffers.append(ctx.depth_renderbuffer(size))
            return ctx.framebuffer(buffers[:1], buffers[1])
        except moderngl.Error as err:
            for buffer in buffers:
                buffer.release()
            refused = f"the driver refused it: {err}"
    raise RenderError(
        f"image size {width}×{height}: this OpenGL context ({ctx.info['GL_RENDERER']}) cannot "
        f"draw it ({refused}); give a smaller image size"
    )


def vertex_array(ctx, program, vbo, ibo) -> moderngl.VertexArray:
    """Bind the interleaved mesh buffer to the attributes ``program`` uses."""
    layout, names = [], []
    for name, width in _ATTRIBUTES:
        if name in program:
            layout.append(f"{width}f")
            names.append(name)
        else:
            layout.append(f"{4 * width}x")
    return ctx.vertex_array(program, [(vbo, " ".join(layout), *names)], ibo)


def mesh_buffers(ctx, mesh) -> tuple[moderngl.Buffer, moderngl.Buffer]:
    """The interleaved vertex buffer (position, normal, uv, tangent) and the index buffer."""
    vertices = np.hstack([
        np.asarray(mesh.positions, np.float32), np.asarray(mesh.normals, np.float32),
        np.asarray(mesh.uvs, np.float32), np.asarray(mesh.tangents, np.float32),
    ])  # fmt: skip
    if not np.all(np.isfinite(vertices)):
        raise RenderError(f"mesh {mesh.name!r}: positions, normals, uvs or tangents hold NaN/inf")
    faces = np.ascontiguousarray(mesh.faces, np.uint32)
    return ctx.buffer(np.ascontiguousarray(vertices)), ctx.buffer(faces)
