"""The simulator: frames the rig's cameras would capture, and their timing.

``Simulator(scene)`` owns one EGL context (through :class:`IdRasterizer`) and
the scene's ray caster. A frame is rendered in stages, each computed only when
the scene lists its effect:

1. face ids by GL — once per (camera, turntable angle), cached and reused for
   every lamp and laser position; exact hits and albedo are reconstructed from
   them in float64, and the hits keep what depends on the view only (specular
   frame, shadow-ray origins) for every lamp;
2. direct light from each lit lamp (Lambertian, + ``specular``, × ``shadows``)
   and the ``laser`` sheet;
3. ``interreflection`` (Mitsuba 3 reference, indirect light only);
4. ``vignetting``, then exposure to digital numbers, ``lens_distortion``;
5. ``noise`` (shot + read), ``saturation`` (clip at full scale), quantisation.

``counters`` counts GL passes, rays and stage invocations. The instance has no
global state; a lock serialises calls, so one server thread (or several) may
call :meth:`render`.
"""

from __future__ import annotations

import threading
import zlib
from collections import Counter, OrderedDict
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rig.camera import PinholeCamera
from rig.timing import StepTiming, motion_s, shots_s
from sim.illumination import direct_radiance, visible_from
from sim.model import SceneModel
from sim.raster import IdRasterizer
from sim.scene import Scene, load_scene
from sim.sensor import (
    add_noise,
    apply_response,
    distort,
    distortion_maps,
    full_scale,
    quantize,
    vignetting_factor,
)
from sim.shading import LightSource, SurfaceHits
from sim.truth import (
    FOOTPRINT_RAYS,
    TexelTruth,
    Truth,
    btf_truth,
    camera_truth,
    image_truth,
    mdf_truth,
    texel_truth,
)
from sim.world import World, WorldSnapshot

__all__ = ["Frame", "Simulator"]

# What the caches may hold, in bytes: the hits of the rig's 8 cameras at one pose
# (~0.2 GB each at --sim's calibration size, 4× supersampled), and shadow masks.
_HITS_CACHE_BYTES = 2 << 30
_SHADOW_CACHE_BYTES = 256 << 20


@dataclass(frozen=True)
class Frame:
    """One simulated camera frame.

    image : (H, W) or (H, W, 3), uint8 (8-bit cameras) or uint16 (10–16 bit),
        values in 0 … 2**bit_depth − 1 (clipped to the dtype's range)
    signal : same shape, float32 — the value before quantisation, in DN (after
        the tone curve when the scene has ``response``)
    timing : how long the capture took (move, settle, exposure and readout), as
        :mod:`rig.timing` models it
    """

    image: np.ndarray
    signal: np.ndarray
    camera_id: str
    snapshot: WorldSnapshot
    exposure_s: float
    bit_depth: int
    effects: tuple[str, ...]
    timing: StepTiming | None = None

    @property
    def metadata(self) -> dict:
        """JSON-serialisable description of the frame."""
        s = self.snapshot
        return {
            "camera": self.camera_id,
            "t": s.t,
            "turntable_deg": s.turntable_deg,
            "arc_deg": s.arc_deg,
            "lamps_on": sorted(s.lamps_on),
            "laser_on": s.laser_on,
            "laser_tilt_deg": s.laser_tilt_deg,
            "laser_mount": s.laser_mount,
            "exposure_s": self.exposure_s,
            "bit_depth": self.bit_depth,
            "dtype": str(self.image.dtype),
            "shape": list(self.image.shape),
            "effects": list(self.effects),
            "timing": None if self.timing is None else self.timing.as_dict(),
        }


class _Lru(OrderedDict):
    """Least recently used values, at most ``max_bytes`` of them (the newest is kept
    whatever its size)."""

    def __init__(self, max_bytes: int):
        super().__init__()
        self.max_bytes = max_bytes

    def put(self, key, value):
        self[key] = value
        self.move_to_end(key)
        while len(self) > 1 and sum(v.nbytes for v in self.values()) > self.max_bytes:
            self.popitem(last=False)
        return value


class Simulator:
    """Render frames of a scene from the rig's cameras. Call :meth:`close`.

    Parameters
    ----------
    scene : Scene, or the path of a scene TOML
    """

    def __init__(self, scene: Scene | str | Path):
        self.scene = scene if isinstance(scene, Scene) else load_scene(scene)
        self.model = SceneModel(self.scene)
        mesh = self.model.mesh
        self.counters: Counter = Counter()
        self._lock = threading.RLock()
        self._raster = IdRasterizer(mesh.vertices, mesh.faces)
        self._hits = _Lru(_HITS_CACHE_BYTES)
        self._shadows = _Lru(_SHADOW_CACHE_BYTES)
        self._sensor: dict = {}
        noise = self.scene.spec.params("noise") if self.scene.has("noise") else None
        self._noise_seed = noise.seed if noise else 0
        # One noise stream per camera: cameras capture in parallel threads, and a
        # shared stream would give each frame the noise of whichever came first.
        self._noise_streams: dict[str, np.random.SeedSequence] = {}
        self._reference = None
        self._compile_passes()

    def _compile_passes(self) -> None:
        """Compile the per-pixel passes (or load them from numba's cache) on empty inputs
        of a frame's types: a camera server's first capture would otherwise wait seconds
        for them, past its timeout."""
        model, none = self.model, np.zeros(0, np.int64)
        hits = model.hits((0, 0), none, np.zeros(3), np.zeros((0, 3)), none)
        lamp = LightSource(np.array([0.0, 0.0, 1000.0]), "point", 1.0)
        lamp.surface_irradiance(hits.points, hits.normals)
        if self.scene.has("shadows") or self.scene.has("laser"):
            model.caster.sees(hits.points, lamp.position, np.zeros(0, bool))
        if self.scene.has("noise"):
            add_noise(np.zeros(1), bit_depth=8, full_well_e=1.0, read_noise_e=1.0,
                      rng=np.random.default_rng(0))  # fmt: skip

    # -- life cycle -------------------------------------------------------
    def close(self) -> None:
        """Release the GL context and the reference renderer (idempotent)."""
        with self._lock:
            self._raster.close()
            self._reference = None

    def __enter__(self) -> Simulator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- frames -----------------------------------------------------------
    def render(
        self, camera_id: str, snapshot: WorldSnapshot, exposure_s: float | None = None
    ) -> Frame:
        """The frame camera ``camera_id`` captures of the world in ``snapshot``.

        Positions are the snapshot's (no motion blur); ``exposure_s`` defaults
        to the scene's ``radiometry.exposure_s``.
        """
        exposure = self._exposure(exposure_s)
        with self._lock:
            camera = self.model.camera(camera_id, snapshot)
            spec = self.scene.rig.camera(camera_id)
            hits = self._pixel_hits(camera_id, snapshot)
            radiance = _area_average(
                self._radiance(camera_id, hits, snapshot), self.scene.spec.render.supersample
            )
            if self.scene.has("interreflection"):
                self.counters["stage.interreflection"] += 1
                radiance += self._indirect(camera_id, snapshot)
            if self.scene.has("vignetting"):
                self.counters["stage.vignetting"] += 1
                radiance *= self._sensor_cache("vignette", camera_id, camera)[..., None]
            signal = self._to_dn(radiance, exposure, spec.bit_depth, spec.channels)
            if self.scene.has("lens_distortion"):
                self.counters["stage.lens_distortion"] += 1
                signal = distort(signal, self._sensor_cache("distortion", camera_id, camera))
            if self.scene.has("noise"):
                self.counters["stage.noise"] += 1
                p = self.scene.spec.params("noise")
                stream = self._noise_streams.setdefault(
                    camera_id,
                    np.random.SeedSequence([self._noise_seed, zlib.crc32(camera_id.encode())]),
                )
                rng = np.random.default_rng(stream.spawn(1)[0])
                signal = add_noise(
                    signal, bit_depth=spec.bit_depth, full_well_e=p.full_well_e,
                    read_noise_e=p.read_noise_e, rng=rng,
                )  # fmt: skip
            if self.scene.has("saturation"):
                self.counters["stage.saturation"] += 1
                signal = np.clip(signal, 0, full_scale(spec.bit_depth), out=signal)
            if self.scene.has("response"):
                self.counters["stage.response"] += 1
                gamma = self.scene.spec.params("response").gamma
                signal = apply_response(signal, bit_depth=spec.bit_depth, gamma=gamma)
            self.counters["frames"] += 1
        dtype = np.uint8 if spec.bit_depth == 8 else np.uint16
        return Frame(
            image=quantize(signal, dtype),
            signal=signal.astype(np.float32),
            camera_id=camera_id,
            snapshot=snapshot,
            exposure_s=exposure,
            bit_depth=spec.bit_depth,
            effects=self.scene.spec.effects,
        )

    def render_state(
        self,
        camera_id: str,
        *,
        turntable_deg: float = 0.0,
        arc_deg: float = 0.0,
        lamps_on=(),
        laser: bool = False,
        laser_tilt_deg: float = 0.0,
        laser_mount: int = 0,
        exposure_s: float | None = None,
    ) -> Frame:
        """:meth:`render` for explicit positions (no World needed)."""
        for lamp in lamps_on:
            self.scene.rig.lamp(lamp)  # validates the id
        snapshot = WorldSnapshot(
            t=0.0,
            turntable_deg=float(turntable_deg),
            arc_deg=float(arc_deg),
            lamps_on=frozenset(lamps_on),
            laser_on=laser,
            laser_tilt_deg=float(laser_tilt_deg),
            laser_mount=laser_mount,
        )
        return self.render(camera_id, snapshot, exposure_s)

    def capture_timing(
        self, camera_id: str, start: WorldSnapshot, *, turntable_deg: float, arc_deg: float,
        exposure_s: float | None = None,
    ) -> StepTiming:  # fmt: skip
        """How long moving from ``start``, settling, exposing and reading out take."""
        rig = self.scene.rig
        move, settle = motion_s(rig, (start.turntable_deg, start.arc_deg), (turntable_deg, arc_deg))
        capture = shots_s(rig, [camera_id], [self._exposure(exposure_s)])
        return StepTiming(float(move), float(settle), 0.0, capture)

    def capture(
        self, world: World, camera_id: str, *, turntable_deg: float, arc_deg: float,
        exposure_s: float | None = None,
    ) -> Frame:  # fmt: skip
        """Move the world's axes, then capture a frame; the frame carries the timing.

        With ``motion_timing`` the world's clock advances through the move, the
        settle time, the exposure and the readout, and the frame shows the
        world as it is after settling (a stalled axis shows where it stopped).
        Without it no time passes and the frame shows the commanded positions.
        """
        exposure = self._exposure(exposure_s)
        timing = self.capture_timing(
            camera_id, world.snapshot(), turntable_deg=turntable_deg, arc_deg=arc_deg,
            exposure_s=exposure,
        )  # fmt: skip
        world.move("turntable", turntable_deg)
        world.move("arc", arc_deg)
        if self.scene.has("motion_timing"):
            self.counters["stage.motion_timing"] += 1
            world.clock.sleep(timing.move_s + timing.settle_s)
            snapshot = world.snapshot()
            world.clock.sleep(timing.capture_s)
        else:
            snapshot = replace(world.snapshot(), turntable_deg=turntable_deg, arc_deg=arc_deg)
        return replace(self.render(camera_id, snapshot, exposure), timing=timing)

    # -- ground truth (ray cast, independent of GL) -----------------------
    def truth(
        self, camera_id: str, turntable_deg: float = 0.0, *, arc_deg: float = 0.0, lamps=()
    ) -> Truth:
        """Per-pixel normals, albedo, height, part and lamp visibility of a camera."""
        with self._lock:
            return camera_truth(self.model, camera_id, turntable_deg, arc_deg=arc_deg, lamps=lamps)

    def image_truth(
        self, camera_id: str, snapshot: WorldSnapshot, exposure_s: float | None = None
    ) -> np.ndarray:
        """Noise-free pinhole image (float32 DN) shaded from ray-cast hits."""
        with self._lock:
            return image_truth(self.model, camera_id, snapshot, self._exposure(exposure_s))

    def mdf_truth(self, view_dir, n: int) -> np.ndarray:
        """(n, n) float32 MDF for view direction (θ, φ) deg; −1 where nothing is hit."""
        with self._lock:
            return mdf_truth(self.model, view_dir, n)

    def texel_truth(self, n: int, *, rays: int = FOOTPRINT_RAYS) -> TexelTruth:
        """Normals, albedo and height on the n×n texel grid (seen from above),
        each texel the mean over its footprint of ``rays`` × ``rays`` rays."""
        with self._lock:
            return texel_truth(self.model, n, rays=rays)

    def btf_truth(self, view_dir, light_dir, n: int, *, rays: int = FOOTPRINT_RAYS) -> np.ndarray:
        """(n, n, 3) float32 BTF slice (radiance per unit distant irradiance),
        each texel the mean over its footprint of ``rays`` × ``rays`` rays."""
        with self._lock:
            return btf_truth(self.model, view_dir, light_dir, n, rays=rays)

    # -- stages -----------------------------------------------------------
    def _exposure(self, exposure_s: float | None) -> float:
        exposure = self.scene.spec.radiometry.exposure_s if exposure_s is None else exposure_s
        if not exposure > 0:
            raise ValueError(f"exposure_s must be > 0, got {exposure_s}")
        return float(exposure)

    def _pixel_hits(self, camera_id: str, snapshot: WorldSnapshot) -> SurfaceHits:
        key = (camera_id, *_pose_key(snapshot))
        turntable_deg = snapshot.turntable_deg
        if key in self._hits:
            self._hits.move_to_end(key)
            return self._hits[key]
        camera = _supersampled(
            self.model.camera(camera_id, snapshot), self.scene.spec.render.supersample
        )
        faces = self._raster.face_ids(camera, turntable_deg)
        self.counters["gl_pass"] += 1
        origin, dirs = self.model.camera_rays(camera, turntable_deg)
        pixels = np.flatnonzero(faces.ravel() >= 0)
        hits = self.model.hits(faces.shape, pixels, origin, dirs[pixels], faces.ravel()[pixels])
        return self._hits.put(key, hits)

    def _radiance(self, camera_id: str, hits: SurfaceHits, snapshot: WorldSnapshot):
        shadows = None
        if self.scene.has("shadows"):
            offset = self.scene.spec.params("shadows").offset_mm

            def shadows(lamp_id, light, lit):
                # What the lamp lights is fixed by the key: the cached mask answers for it.
                key = (camera_id, *_pose_key(snapshot), lamp_id, round(snapshot.arc_deg, 9))
                if key not in self._shadows:
                    self.counters["raycast.shadows"] += 1
                    self._shadows.put(key, visible_from(self.model, hits, light.position,
                                                        offset_mm=offset, where=lit))  # fmt: skip
                return self._shadows[key]

        laser = self.scene.spec.params("laser") if self.scene.has("laser") else None
        values = direct_radiance(
            self.model, hits, snapshot, counters=self.counters, shadow_mask=shadows,
            laser=laser, specular=self.scene.has("specular"),
        )  # fmt: skip
        image = np.zeros((*hits.shape, 3))
        image.reshape(-1, 3)[hits.pixels] = values
        return image

    def _to_dn(self, radiance, exposure, bit_depth, channels) -> np.ndarray:
        radiometry = self.scene.spec.radiometry
        # In place: the radiance image is this frame's own.
        radiance *= exposure / radiometry.full_scale_exposure * full_scale(bit_depth)
        return radiance.mean(axis=2) if channels == 1 else radiance

    def _sensor_cache(self, kind: str, camera_id: str, camera):
        key = (kind, camera_id)
        if key not in self._sensor:
            if kind == "vignette":
                exponent = self.scene.spec.params("vignetting").exponent
                self._sensor[key] = vignetting_factor(camera, exponent)
            else:
                self._sensor[key] = distortion_maps(camera)
        return self._sensor[key]

    def _indirect(self, camera_id: str, snapshot: WorldSnapshot) -> np.ndarray:
        from sim.reference import MitsubaReference

        if self._reference is None:
            self._reference = MitsubaReference(
                self.model, self.scene.spec.params("interreflection")
            )
        return self._reference.indirect(camera_id, snapshot)


def _pose_key(snapshot: WorldSnapshot) -> tuple:
    """What places the cameras relative to the sample: the turntable, or the Bonn
    lab's plate orientation and rail (rounded: the caches' keys)."""
    rotation = snapshot.sample_rotation or ()
    return (round(snapshot.turntable_deg, 9), round(snapshot.rail_deg, 9),
            *(round(r, 9) for r in rotation))  # fmt: skip


def _supersampled(camera: PinholeCamera, k: int) -> PinholeCamera:
    """The camera with k×k sub-pixels per pixel, centred in their pixel."""
    if k == 1:
        return camera
    K = camera.K.copy()
    K[:2] *= k
    K[0, 2] = (camera.K[0, 2] + 0.5) * k - 0.5
    K[1, 2] = (camera.K[1, 2] + 0.5) * k - 0.5
    return PinholeCamera(K, camera.dist, camera.R, camera.t, camera.width * k, camera.height * k)


def _area_average(image: np.ndarray, k: int) -> np.ndarray:
    """(H·k, W·k, C) → (H, W, C): each pixel the mean of its k×k sub-pixels."""
    if k == 1:
        return image
    # A sum of the k² strided sub-images: a mean over the reshaped axes (1, 3)
    # walks memory k·k times slower.
    total = image[::k, ::k].copy()
    for i in range(k):
        for j in range(k):
            if i or j:
                total += image[i::k, j::k]
    total *= 1.0 / (k * k)
    return total
