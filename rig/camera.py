"""The camera models shared by the simulator, calibration and processing.

``PinholeCamera`` is the rig's cameras; ``OrthographicCamera`` is a telecentric
lens or a camera so far from a small target (a mirror sphere in a distant
setup) that its rays are parallel.

OpenCV conventions: the camera looks along its +z axis, x to the right, y down;
a world point ``X`` maps to camera coordinates ``R @ X + t``; lens distortion
is Brown–Conrady with coefficients ``(k1, k2, p1, p2, k3)`` as in
``cv2.projectPoints``. Lengths are in millimetres, pixels have their centre at
integer coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["OrthographicCamera", "PinholeCamera", "look_at"]


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """World→camera rotation ``R`` and translation ``t`` of a camera at ``eye``
    looking at ``target``, with image "up" as close to ``up`` as possible.

    Raises ``ValueError`` when ``eye`` equals ``target``. When the view axis is
    parallel to ``up`` the world x axis is used as a fallback up direction.
    """
    eye = np.asarray(eye, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    forward = target - eye
    dist = np.linalg.norm(forward)
    if dist == 0:
        raise ValueError("look_at: eye and target are the same point")
    z = forward / dist
    up = np.asarray(up, dtype=np.float64)
    if np.linalg.norm(_cross(z, up)) < 1e-9:
        up = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = _cross(z, -up)  # image y points down, so "up" is -y
    x /= np.linalg.norm(x)
    y = _cross(z, x)
    R = np.stack([x, y, z])
    return R, -R @ eye


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of two 3-vectors, in its arithmetic: its axis handling took most of a
    camera model's construction, which registration does for every frame."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


@dataclass(frozen=True)
class PinholeCamera:
    """Intrinsics, distortion and pose of one camera.

    Parameters
    ----------
    K : (3, 3) float64
        Intrinsic matrix, pixels.
    dist : (5,) float64
        Brown–Conrady ``(k1, k2, p1, p2, k3)``.
    R : (3, 3) float64
        World→camera rotation.
    t : (3,) float64
        World→camera translation, mm.
    width, height : int
        Image size in pixels.
    """

    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    t: np.ndarray
    width: int
    height: int

    def __post_init__(self) -> None:
        for name, shape in (("K", (3, 3)), ("dist", (5,)), ("R", (3, 3)), ("t", (3,))):
            value = np.array(getattr(self, name), dtype=np.float64)
            if value.shape != shape or not np.all(np.isfinite(value)):
                raise ValueError(f"PinholeCamera.{name}: expected finite {shape}, got {value}")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        # np.allclose(R Rᵀ, I, atol=1e-9) written out (R is finite): its checks took
        # a third of a camera model's construction.
        identity = np.eye(3)
        if not np.all(np.abs(self.R @ self.R.T - identity) <= 1e-9 + 1e-5 * identity):
            raise ValueError("PinholeCamera.R is not a rotation matrix")

    def scaled(self, scale: float) -> PinholeCamera:
        """The same camera with its image resampled by ``scale`` (binned: fewer pixels).

        Pixel centres stay on the same rays: ``c' = (c + ½)·scale − ½``; the size
        rounds as the archive's frame formats do.
        """
        if not scale > 0:
            raise ValueError(f"PinholeCamera.scaled: scale={scale} must be > 0")
        if scale == 1.0:
            return self
        K = self.K.copy()
        K[:2, :2] *= scale
        K[:2, 2] = (K[:2, 2] + 0.5) * scale - 0.5
        width, height = max(1, round(self.width * scale)), max(1, round(self.height * scale))
        return PinholeCamera(K, self.dist, self.R, self.t, width, height)

    @property
    def center(self) -> np.ndarray:
        """(3,) camera centre in world coordinates, mm."""
        return -self.R.T @ self.t

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates of world points.

        Returns
        -------
        pixels : (n, 2) float64
        in_front : (n,) bool
            False for points at or behind the camera plane (their pixels are
            not meaningful and are set to -1).
        """
        X = np.atleast_2d(np.asarray(points, dtype=np.float64)) @ self.R.T + self.t
        in_front = X[:, 2] > 1e-9
        z = np.where(in_front, X[:, 2], 1.0)
        xn = np.stack([X[:, 0] / z, X[:, 1] / z], axis=1)
        xd = self._distort(xn)
        pix = xd @ self.K[:2, :2].T + self.K[:2, 2]
        pix[~in_front] = -1.0
        return pix, in_front

    def rays(self, pixels) -> tuple[np.ndarray, np.ndarray]:
        """World-space rays through pixel coordinates.

        Returns
        -------
        origin : (3,) float64
            The camera centre.
        directions : (n, 3) float64
            Unit direction of each pixel's ray.
        """
        pix = np.atleast_2d(np.asarray(pixels, dtype=np.float64))
        xd = np.linalg.solve(self.K[:2, :2], (pix - self.K[:2, 2]).T).T
        xn = self._undistort(xd)
        d_cam = np.column_stack([xn, np.ones(len(xn))])
        d = d_cam @ self.R  # R.T @ d for each row
        return self.center, d / np.linalg.norm(d, axis=1, keepdims=True)

    def _distort(self, xn: np.ndarray) -> np.ndarray:
        k1, k2, p1, p2, k3 = self.dist
        if not np.any(self.dist):
            return xn
        x, y = xn[:, 0], xn[:, 1]
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        return np.stack([xd, yd], axis=1)

    def _undistort(self, xd: np.ndarray, iterations: int = 20) -> np.ndarray:
        # Fixed-point inversion of the Brown–Conrady model, as cv2.undistortPoints.
        if not np.any(self.dist):
            return xd
        k1, k2, p1, p2, k3 = self.dist
        x, y = xd[:, 0].copy(), xd[:, 1].copy()
        for _ in range(iterations):
            r2 = x * x + y * y
            radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
            dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
            dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
            x = (xd[:, 0] - dx) / radial
            y = (xd[:, 1] - dy) / radial
        return np.stack([x, y], axis=1)


@dataclass(frozen=True)
class OrthographicCamera:
    """A telecentric (orthographic) camera: parallel rays along its +z axis.

    Camera coordinates as ``PinholeCamera`` (``R @ X + t``, x right, y down);
    a point's pixel is ``(x, y) / mm_per_px`` plus the image centre, whatever
    its depth. Rays start on the plane z = 0 of the camera frame.

    Parameters
    ----------
    R : (3, 3) float64
        World→camera rotation.
    t : (3,) float64
        World→camera translation, mm.
    mm_per_px : float
        Side of one pixel's footprint, mm (1 where the scale is unknown: the
        lengths are then in pixels).
    width, height : int
        Image size in pixels.
    """

    R: np.ndarray
    t: np.ndarray
    mm_per_px: float
    width: int
    height: int

    def __post_init__(self) -> None:
        for name, shape in (("R", (3, 3)), ("t", (3,))):
            value = np.array(getattr(self, name), dtype=np.float64)
            if value.shape != shape or not np.all(np.isfinite(value)):
                raise ValueError(f"OrthographicCamera.{name}: expected finite {shape}, got {value}")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        if not np.allclose(self.R @ self.R.T, np.eye(3), atol=1e-9):
            raise ValueError("OrthographicCamera.R is not a rotation matrix")
        if not (np.isfinite(self.mm_per_px) and self.mm_per_px > 0):
            raise ValueError(f"OrthographicCamera.mm_per_px={self.mm_per_px}: must be > 0")

    @classmethod
    def looking_down(
        cls, width: int, height: int, *, mm_per_px: float = 1.0, height_mm: float = 1000.0
    ) -> OrthographicCamera:
        """A camera above the origin looking down −z: image x is world +x, image
        up is world +y, so directions come out in the frame photometric-stereo
        data sets use (x right, y up, z towards the camera)."""
        R = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
        return cls(R, np.array([0.0, 0.0, height_mm]), mm_per_px, width, height)

    @property
    def towards_camera(self) -> np.ndarray:
        """(3,) unit world direction from the scene towards the camera."""
        return -self.R[2].copy()

    def project(self, points) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates of world points, as ``PinholeCamera.project``
        (``in_front`` is False for points behind the plane z = 0)."""
        X = np.atleast_2d(np.asarray(points, dtype=np.float64)) @ self.R.T + self.t
        centre = np.array([(self.width - 1) / 2, (self.height - 1) / 2])
        return X[:, :2] / self.mm_per_px + centre, X[:, 2] > 0

    def rays(self, pixels) -> tuple[np.ndarray, np.ndarray]:
        """World-space rays through pixel coordinates.

        Returns
        -------
        origins : (n, 3) float64
            Each ray's start on the camera frame's plane z = 0.
        directions : (n, 3) float64
            The view axis, the same unit vector for every ray.
        """
        pix = np.atleast_2d(np.asarray(pixels, dtype=np.float64))
        centre = np.array([(self.width - 1) / 2, (self.height - 1) / 2])
        xy = (pix - centre) * self.mm_per_px
        cam = np.column_stack([xy, np.zeros(len(xy))])
        origins = (cam - self.t) @ self.R  # R.T @ (x − t) for each row
        return origins, np.broadcast_to(self.R[2], origins.shape).copy()
