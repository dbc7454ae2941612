"""Cameras: where the eye is, where it looks, and the image it makes.

Scene units are the mesh's (mm for the built-in meshes). Matrices follow
OpenGL: right-handed eye space looking down −z, clip space z in [−1, 1], and
are returned as row-major float32 (transpose for a column-major upload).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from render._errors import RenderError

__all__ = ["Camera"]


def _vector(name: str, value) -> np.ndarray:
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise RenderError(f"camera {name} = {value!r}: expected three finite numbers (x, y, z)")
    return v


@dataclass(frozen=True)
class Camera:
    """A look-at camera, perspective or orthographic.

    Build it with :meth:`perspective` or :meth:`orthographic`.

    Attributes
    ----------
    eye, target : (3,) float64
        Camera position and the point it looks at, scene units.
    up : (3,) float64
        Roughly the image's up direction; when it is parallel to the line of
        sight, +y (or +x) of the scene stands in.
    size : (int, int)
        Image width and height in pixels.
    fov_deg : float or None
        Vertical field of view of a perspective camera.
    height : float or None
        Height of the view of an orthographic camera, scene units.
    """

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray
    size: tuple[int, int]
    fov_deg: float | None = None
    height: float | None = None

    @classmethod
    def perspective(cls, eye, target=(0, 0, 0), *, up=(0, 0, 1), fov_deg=35.0, size=(256, 256)):
        """A pinhole camera with vertical field of view ``fov_deg`` (0 < fov < 180)."""
        if not 0 < fov_deg < 180:
            raise RenderError(f"camera fov_deg = {fov_deg}: valid is 0 < fov_deg < 180")
        return cls._checked(eye, target, up, size, fov_deg=float(fov_deg))

    @classmethod
    def orthographic(cls, eye, target=(0, 0, 0), *, up=(0, 0, 1), height=100.0, size=(256, 256)):
        """A parallel projection showing ``height`` scene units from the image's bottom to top."""
        if not (np.isfinite(height) and height > 0):
            raise RenderError(f"camera height = {height}: must be a positive size in scene units")
        return cls._checked(eye, target, up, size, height=float(height))

    @classmethod
    def _checked(cls, eye, target, up, size, **kind) -> Camera:
        eye, target, up = _vector("eye", eye), _vector("target", target), _vector("up", up)
        if np.linalg.norm(target - eye) == 0:
            raise RenderError(f"camera eye and target are the same point {eye.tolist()}")
        if np.linalg.norm(up) == 0:
            raise RenderError("camera up = (0, 0, 0): give the image's up direction")
        w, h = (int(s) for s in size) if len(size) == 2 else (0, 0)
        if not (1 <= w <= 16384 and 1 <= h <= 16384) or tuple(size) != (w, h):
            raise RenderError(f"camera size = {size!r}: expected (width, height), 1…16384 pixels")
        return cls(eye, target, up, (w, h), **kind)

    @property
    def forward(self) -> np.ndarray:
        """Unit vector from the eye to the target."""
        d = self.target - self.eye
        return d / np.linalg.norm(d)

    def view_matrix(self) -> np.ndarray:
        """World → eye space, (4, 4) float32."""
        f = self.forward
        for up in (self.up, np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])):
            side = np.cross(f, up)
            if np.linalg.norm(side) > 1e-6 * np.linalg.norm(up):
                break
        side /= np.linalg.norm(side)
        true_up = np.cross(side, f)
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = side, true_up, -f
        m[:3, 3] = -m[:3, :3] @ self.eye
        return m.astype(np.float32)

    def projection_matrix(self, near: float, far: float) -> np.ndarray:
        """Eye → clip space for depths ``near`` < ``far`` along the sight line, (4, 4) float32."""
        aspect = self.size[0] / self.size[1]
        p = np.zeros((4, 4))
        if self.fov_deg is not None:
            t = 1.0 / np.tan(np.deg2rad(self.fov_deg) / 2)
            p[0, 0], p[1, 1] = t / aspect, t
            p[2, 2], p[2, 3] = (far + near) / (near - far), 2 * far * near / (near - far)
            p[3, 2] = -1.0
        else:
            half = self.height / 2
            p[0, 0], p[1, 1] = 1 / (half * aspect), 1 / half
            p[2, 2], p[2, 3] = -2 / (far - near), -(far + near) / (far - near)
            p[3, 3] = 1.0
        return p.astype(np.float32)

    def pixel_rays(self) -> tuple[np.ndarray, np.ndarray]:
        """Origins and unit directions of the rays through the pixel centres, as
        :meth:`render.points.renderer.Renderer.render` lays out its image (row 0 at the top):
        (H, W, 3) float64 each, scene units. A ray tracer that casts them sees what
        each pixel of the rendered image shows."""
        inverse = np.linalg.inv(self.view_matrix().astype(np.float64))
        width, height = self.size
        half_h = self.height / 2 if self.fov_deg is None else np.tan(np.deg2rad(self.fov_deg) / 2)
        half_w = half_h * width / height
        x = ((np.arange(width) + 0.5) / width * 2 - 1) * half_w
        y = (1 - (np.arange(height) + 0.5) / height * 2) * half_h
        xx, yy = np.meshgrid(x, y)
        if self.fov_deg is None:  # parallel rays from the image plane through the eye
            local = np.stack([xx, yy, np.zeros_like(xx)], axis=-1)
            origins = local @ inverse[:3, :3].T + inverse[:3, 3]
            return origins, np.broadcast_to(self.forward, origins.shape).copy()
        local = np.stack([xx, yy, -np.ones_like(xx)], axis=-1)
        directions = local @ inverse[:3, :3].T
        directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
        return np.broadcast_to(self.eye, directions.shape).copy(), directions

    def depth_range(self, center, radius: float) -> tuple[float, float]:
        """Near and far planes that hold a bounding sphere (``center``, ``radius``)."""
        distance = float(np.dot(np.asarray(center) - self.eye, self.forward))
        far = max(distance + radius, 1e-3) * 1.01
        if self.fov_deg is None:
            return distance - radius * 1.01 - 1e-3 * far, far
        return max(distance - radius * 1.01, far * 1e-4), far
