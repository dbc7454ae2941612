"""Rasterise which triangle each camera pixel sees: pyrender on headless EGL.

One GL pass per (camera, turntable angle) writes a face-id image (each face
carries its id + 1 as a flat 24-bit RGB vertex colour, 0 is background). The
shading is not done in GL: :mod:`sim.shading` reconstructs the exact hit point
of every pixel's ray on its face, so the GL precision never enters the image.

pyrender's offscreen renderer always draws into a 4× multisampled framebuffer
and resolves it with a blit; MSAA would blend ids at triangle edges and costs
2–4× on llvmpipe, so :class:`_SingleSampleRenderer` allocates single-sample
buffers instead.
"""

from __future__ import annotations

import os
import threading

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np
import pyrender
from OpenGL import GL
from pyrender.platforms import egl

from rig.camera import PinholeCamera

__all__ = ["IdRasterizer", "camera_pose_gl"]

_ZNEAR_MM = 5.0
_ZFAR_MM = 20000.0
#: Farther than anything the rasteriser draws is from the turntable centre (plate, holder).
_SCENE_RADIUS_MM = 1000.0
# OpenCV camera axes (x right, y down, z forward) → OpenGL (x right, y up, z back).
_CV_TO_GL = np.diag([1.0, -1.0, -1.0])


class _SingleSampleRenderer(pyrender.Renderer):
    """pyrender's renderer with single-sample offscreen buffers (no forced MSAA)."""

    def _configure_main_framebuffer(self):
        dims = (self.viewport_width, self.viewport_height)
        if self._main_fb is not None and self._main_fb_dims == dims:
            return
        if self._main_fb is not None:
            self._delete_main_framebuffer()
        # pyrender draws into the "_ms" buffer and blits it into the plain one;
        # both are single-sample here, so the blit is a plain copy.
        fbs, cbs, dbs = [], [], []
        for _ in range(2):
            cb, db = GL.glGenRenderbuffers(2)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, cb)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_RGBA8, *dims)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, db)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_DEPTH_COMPONENT24, *dims)
            fb = GL.glGenFramebuffers(1)
            GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, fb)
            GL.glFramebufferRenderbuffer(
                GL.GL_DRAW_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER, cb
            )
            GL.glFramebufferRenderbuffer(
                GL.GL_DRAW_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_RENDERBUFFER, db
            )
            fbs.append(fb)
            cbs.append(cb)
            dbs.append(db)
        self._main_fb, self._main_fb_ms = fbs
        self._main_cb, self._main_cb_ms = cbs
        self._main_db, self._main_db_ms = dbs
        self._main_fb_dims = dims

    def _read_main_framebuffer(self, scene, flags):
        """The colour buffer as drawn, (H, W, 3) uint8, and no depth: pyrender's reads
        and linearises the depth image too and copies both buffers first (a third
        of a pass on llvmpipe); the ids need neither."""
        width, height = self._main_fb_dims
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._main_fb_ms)
        buffer = GL.glReadPixels(0, 0, width, height, GL.GL_RGB, GL.GL_UNSIGNED_BYTE)
        color = np.frombuffer(buffer, dtype=np.uint8).reshape(height, width, 3)
        return color[::-1], None


class _SharedDisplayEGL(egl.EGLPlatform):
    """pyrender's EGL platform, with a real release and a shared display.

    pyrender's ``make_uncurrent`` does nothing, so the context stays bound to
    the thread that last rendered and any other thread gets EGL_BAD_ACCESS;
    here it unbinds. All contexts on a device share one EGLDisplay — every
    Simulator's, and any other EGL user's in the process (a GL renderer's);
    pyrender terminates it when any one context is deleted, which destroys
    all the others. Here only the context is destroyed: the display stays
    initialised until the process ends.
    """

    def make_uncurrent(self):
        from OpenGL.EGL import EGL_NO_CONTEXT, EGL_NO_SURFACE, eglMakeCurrent

        if not eglMakeCurrent(self._egl_display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT):
            raise RuntimeError("EGL: could not release the context")

    def delete_context(self):
        from OpenGL.EGL import eglDestroyContext

        if self._egl_display is None:
            return
        if self._egl_context is not None:
            eglDestroyContext(self._egl_display, self._egl_context)
            self._egl_context = None
        self._egl_display = None


def camera_pose_gl(camera: PinholeCamera, turntable_deg: float) -> np.ndarray:
    """4×4 camera-to-sample pose in OpenGL axes for a turntable angle.

    The sample frame is the world frame turned by the turntable angle, so a
    fixed camera seen from the sample turns by −α about z.
    """
    a = np.deg2rad(-turntable_deg)
    rz = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    pose = np.eye(4)
    pose[:3, :3] = rz @ camera.R.T @ _CV_TO_GL
    pose[:3, 3] = rz @ camera.center
    return pose


class IdRasterizer:
    """Face-id images of one triangle mesh from pinhole cameras (one EGL context).

    Parameters
    ----------
    vertices : (V, 3) float64
        Sample-frame vertex positions, mm.
    faces : (F, 3) int
        Triangles; at most 2**24 - 1 of them.

    Notes
    -----
    Create once and reuse: the GL context, the scene and the uploaded mesh live
    until :meth:`close`. Calls are serialised by a lock, and the context is made
    current on the calling thread for each call, so any one thread at a time
    may render.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        n_faces = len(faces)
        if n_faces >= 2**24 - 1:
            raise ValueError(f"IdRasterizer: {n_faces} faces exceed the 24-bit id range")
        ids = np.arange(1, n_faces + 1, dtype=np.uint32)
        rgb = np.stack([(ids >> 16) & 255, (ids >> 8) & 255, ids & 255], axis=1)
        colors = np.repeat(np.column_stack([rgb, np.full(n_faces, 255)]).astype(np.uint8), 3, 0)
        positions = np.asarray(vertices, dtype=np.float32)[np.asarray(faces).reshape(-1)]
        material = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=(1.0, 1.0, 1.0, 1.0), doubleSided=True
        )
        prim = pyrender.Primitive(positions=positions, color_0=colors, material=material)
        self._scene = pyrender.Scene(bg_color=(0.0, 0.0, 0.0, 0.0), ambient_light=(0, 0, 0))
        self._scene.add(pyrender.Mesh([prim]))
        self._cam_node = None
        self._lock = threading.Lock()
        self._platform = _SharedDisplayEGL(64, 64, device=egl.get_device_by_index(0))
        self._platform.init_context()
        self._platform.make_current()
        self._renderer = _SingleSampleRenderer(64, 64)
        self._platform.make_uncurrent()
        self.passes = 0  # GL passes drawn, for the cost accounting

    def face_ids(self, camera: PinholeCamera, turntable_deg: float) -> np.ndarray:
        """(H, W) int32 face index seen by each pixel centre, −1 for background.

        The camera's lens distortion is ignored here: this is the pinhole image.
        """
        K = camera.K
        # A camera far away (a telecentric stand-in) keeps its depth buffer's precision
        # with the clip planes around the sample: the planes' ratio sets it.
        distance = float(np.linalg.norm(camera.center))
        znear = max(_ZNEAR_MM, distance - _SCENE_RADIUS_MM)
        zfar = max(_ZFAR_MM, distance + _SCENE_RADIUS_MM)
        # pyrender puts pixel i's centre at i + ½; OpenCV at i.
        gl_cam = pyrender.IntrinsicsCamera(
            fx=K[0, 0], fy=K[1, 1], cx=K[0, 2] + 0.5, cy=K[1, 2] + 0.5, znear=znear, zfar=zfar,
        )  # fmt: skip
        pose = camera_pose_gl(camera, turntable_deg)
        with self._lock:
            if self._renderer is None:
                raise RuntimeError("IdRasterizer is closed")
            if self._cam_node is not None:
                self._scene.remove_node(self._cam_node)
            self._cam_node = self._scene.add(gl_cam, pose=pose)
            self._platform.make_current()
            try:
                self._renderer.viewport_width = camera.width
                self._renderer.viewport_height = camera.height
                flags = pyrender.RenderFlags.OFFSCREEN | pyrender.RenderFlags.FLAT
                color, _ = self._renderer.render(self._scene, flags)
            finally:
                self._platform.make_uncurrent()
            self.passes += 1
        c = color.astype(np.int32)
        return ((c[..., 0] << 16) | (c[..., 1] << 8) | c[..., 2]) - 1

    def close(self) -> None:
        """Release the GL objects and the EGL context (idempotent)."""
        with self._lock:
            if self._renderer is None:
                return
            self._platform.make_current()
            self._renderer.delete()
            self._platform.make_uncurrent()
            self._platform.delete_context()
            self._renderer = None
            self._platform = None
