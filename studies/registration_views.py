"""Registration against the simulator: rendered frames and their true normtextures.

The scene is a flat Lambertian sample 0.01 mm below the reference plane (so the
perspective of the camera adds no parallax) with a smooth albedo texture, lit by
directional lamps: the radiance at a texel is then ρ(x, y)/π · E · cosθ_l for
every view, and the true normtexture is the simulator's ``btf_truth`` (computed
by ray casting, independent of the rasteriser) times the irradiance and the
camera's DN scale, box-averaged over each texel.

A real sensor integrates over each pixel's area: frames here are rendered with the
scene's ``render.supersample = oversample`` (``oversample``² shading points per
pixel, averaged), then quantised — with the simulator's own shot and read noise
model applied to the same signal for the noisy variant. Point-sampled frames
(``oversample = 1``) alias the marker edges and cost 0.1–0.5 px of corner accuracy
(see ``docs/btf.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.registration import Registration, marker_corners_mm, rectify, register_frame
from rig.config import RigConfig, default_rig_config
from rig.geometry import Sampling
from rig.kinematics import forward, inverse
from sim import Simulator, scene_from_dict
from sim.sensor import add_noise, full_scale, quantize

ALBEDO_RGB = (0.6, 0.5, 0.4)
FULL_WELL_E = 10000.0
READ_NOISE_E = 5.0


def registration_scene(scale: float, supersample: int = 1, effects: tuple[str, ...] = ()):
    """The flat Lambertian scene with directional lamps, cameras at ``scale``."""
    lamps = [
        {"id": lamp.id, "theta_deg": lamp.theta_deg, "kind": "directional"}
        for lamp in default_rig_config().light_arc.lamps
    ]
    albedo = {"kind": "noise", "rgb": list(ALBEDO_RGB), "variation": 0.3, "scale_mm": 8.0}
    return scene_from_dict({
        "name": "registration",
        "effects": list(effects),
        "sample": {"generator": "flat", "depth_mm": 0.01, "materials": ["m"]},
        "materials": {"m": {"albedo": albedo}},
        "rig": {"overrides": {"light_arc": {"lamps": lamps}}},
        "render": {"scale": scale, "supersample": supersample},
    })  # fmt: skip


def h1_views(max_theta_deg: float = 75.0) -> np.ndarray:
    """(n, 2) H1 view directions (θ, φ) deg with θ ≤ ``max_theta_deg``."""
    h1 = Sampling.named("H1").directions
    return h1[h1[:, 0] <= max_theta_deg]


def dn_per_btf_unit(config: RigConfig, lamp_id: str, radiometry, exposure_s: float) -> float:
    """DN of the camera per unit of ``btf_truth`` (1/sr) under a directional lamp.

    E = I · k / r² (W/m², r in m, the irradiance the lamp gives at the
    turntable centre), radiance = btf · E, DN = radiance · t / H_fs · (2^bits − 1)
    (docs/sim.md, image formation).
    """
    lamp = config.lamp(lamp_id)
    r_m = config.light_arc.radius_mm / 1000.0
    irradiance = radiometry.intensity_w_sr * lamp.intensity / r_m**2
    bits = config.camera_arc.cameras[0].bit_depth
    return irradiance * exposure_s / radiometry.full_scale_exposure * full_scale(bits)


@dataclass(frozen=True)
class ViewResult:
    """One view: where the rig was, and how registration did (clean and noisy)."""

    view_deg: tuple[float, float]
    achieved_view_deg: tuple[float, float]
    camera: str
    turntable_deg: float
    clean: Registration
    noisy: Registration
    corner_error_px: float  # mean distance of the found corners to their true projection
    texture_rmse: float  # clean normtexture vs truth, relative to the mean true value
    noisy_texture_rmse: float
    noise_rmse: float  # the noise alone, same units (expected floor of noisy_texture_rmse)
    texture_gain: float  # mean clean normtexture / mean truth (radiometric check, ≈ 1)


class SimRegistration:
    """Render anti-aliased frames of the registration scene and register them.

    Parameters
    ----------
    scale : float
        Render scale of the cameras the frames are registered for.
    oversample : int
        Shading points per pixel and axis (``render.supersample``).
    size : int
        N of the normtextures.
    """

    def __init__(self, *, scale: float = 0.5, oversample: int = 3, size: int = 64, seed: int = 0):
        self.scene = registration_scene(scale)
        self.config = self.scene.rig
        self.oversample = oversample
        self.size = size
        self._sim = Simulator(registration_scene(scale, oversample))
        self._rng = np.random.default_rng(seed)
        self._truth: dict[tuple, np.ndarray] = {}

    def close(self) -> None:
        self._sim.close()

    def __enter__(self) -> SimRegistration:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _frames(self, camera: str, turntable_deg: float, arc_deg: float, lamp: str):
        frame = self._sim.render_state(
            camera, turntable_deg=turntable_deg, arc_deg=arc_deg, lamps_on=[lamp]
        )
        signal = frame.signal.astype(np.float64)
        bits = frame.bit_depth
        noisy = add_noise(
            signal, bit_depth=bits, full_well_e=FULL_WELL_E, read_noise_e=READ_NOISE_E,
            rng=self._rng,
        )  # fmt: skip
        dtype = np.uint8 if bits == 8 else np.uint16
        return signal, quantize(signal, dtype), quantize(noisy, dtype)

    def true_texture(self, light_deg, lamp: str, *, supersample: int = 4) -> np.ndarray:
        """(N, N, 3) float64 DN: texel averages of the true normtexture."""
        key = (tuple(np.round(light_deg, 9)), lamp)
        if key not in self._truth:
            n, s = self.size, supersample
            # Lambertian and flat at z ≈ 0: the same for every view; frontal view.
            texels = self._sim.btf_truth((0.0, 0.0), tuple(light_deg), n, rays=s)
            radiometry = self.scene.spec.radiometry
            scale = dn_per_btf_unit(self.config, lamp, radiometry, radiometry.exposure_s)
            self._truth[key] = texels.astype(np.float64) * scale
        return self._truth[key]

    def run(self, view_deg, light_deg=(0.0, 0.0)) -> ViewResult:
        """Pose the rig for a direction pair, render, register, compare with the truth."""
        config = self.config
        pose = inverse(config, tuple(view_deg), tuple(light_deg))
        view, light = forward(
            config, turntable_deg=pose.turntable_deg, arc_deg=pose.arc_deg,
            camera=pose.camera, lamp=pose.lamp,
        )  # fmt: skip
        signal, clean_frame, noisy_frame = self._frames(
            pose.camera, pose.turntable_deg, pose.arc_deg, pose.lamp
        )
        camera = config.camera_model(pose.camera, turntable_deg=pose.turntable_deg)
        holder = config.holder
        # The markers are looked for where the rig's pose puts them, as register_capture does.
        clean = register_frame(clean_frame, holder, size=self.size, camera=camera, expected=camera)
        noisy = register_frame(noisy_frame, holder, size=self.size, camera=camera, expected=camera)
        truth = self.true_texture(light, pose.lamp)
        corner_error = np.nan
        texture_rmse = noisy_rmse = noise_rmse = gain = np.nan
        if len(clean.detection):
            plate = marker_corners_mm(holder)[clean.detection.ids].reshape(-1, 2)
            points = np.column_stack([plate, np.zeros(len(plate))])
            projected, _ = camera.project(points)
            found = clean.detection.corners_px.reshape(-1, 2)
            corner_error = float(np.linalg.norm(found - projected, axis=1).mean())
        reference = float(truth.mean())
        if clean.valid:
            texture_rmse = _rmse(clean, truth) / reference
            inner = (slice(1, -1), slice(1, -1))  # the edge texels see the plate's white
            valid = clean.normtexture.valid[inner]
            tex = clean.normtexture.texture[inner][valid]
            gain = float(tex.mean() / truth[inner][valid].mean())
        if noisy.valid:
            noisy_rmse = _rmse(noisy, truth) / reference
            # The noise alone, rectified with the clean homography.
            if clean.valid:
                diff = noisy_frame.astype(np.float64) - signal
                noise_tex = rectify(
                    diff, clean.homography, sample_mm=holder.sample_mm, size=self.size,
                    camera=camera,
                )  # fmt: skip
                noise_rmse = float(np.sqrt(np.mean(noise_tex.texture[1:-1, 1:-1] ** 2)))
                noise_rmse /= reference
        return ViewResult(
            (float(view_deg[0]), float(view_deg[1])), (float(view[0]), float(view[1])),
            pose.camera, pose.turntable_deg, clean, noisy, corner_error,
            texture_rmse, noisy_rmse, noise_rmse, gain,
        )  # fmt: skip


def _rmse(result: Registration, truth: np.ndarray) -> float:
    """RMS difference over the interior texels (one texel off the recess edge)."""
    texture = result.normtexture.texture.astype(np.float64)
    inner = (slice(1, -1), slice(1, -1))
    valid = result.normtexture.valid[inner]
    diff = (texture - truth)[inner][valid]
    return float(np.sqrt(np.mean(diff**2)))
