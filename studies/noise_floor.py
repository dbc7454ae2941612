"""The PSNR floor the sensor model implies: the loop's score if noise were its only error.

Derived from the sensor model (``sim.sensor``), never by running the loop twice:

1. **A pixel.** Its signal s (DN) is the noise-free truth in DN,
   ``truth · scale · full_scale · exposure`` (``scale``:
   :func:`studies.render_loop.irradiance_scale`, the lamp's irradiance at the
   turntable centre); its variance is shot + read + quantisation noise,
   ``s·g + (σ_read·g)² + 1/12`` DN² with g = full scale / full well DN per
   electron (:func:`sim.sensor.add_noise`; quantisation alone when the scene lists
   no ``noise``). The near lamps' irradiance, −15…+17 % across the sample, is
   taken as the centre's: it enters the shot variance linearly and its mean over
   the texels is within 0.4 % of the centre's on the default rig (0.02 dB).
2. **A texel.** Registration averages pixels into texels with weights w_p, so
   the texel's variance is Σ w_p² times the pixel's (the signal is nearly
   constant over one footprint). :func:`texel_noise_gain` derives Σ w_p² from the
   camera's pose and the filter's sub-grid (:func:`processing.registration.subgrid`),
   averaged over the sub-pixel phase of the texel grid against the pixel grid.
3. **The stored value.** The btf stage divides DN by full scale · exposure, the
   score divides by ``scale``: the variance in ``btf_truth`` units is the texel's
   over (scale · full_scale · exposure)².
4. **Compression.** The per-view PCA reconstructs light l from the slot's mean
   over the lights and c components: a projection in light space whose diagonal
   P_ll (:func:`leverage`) is the share of light l's noise that survives, if
   the noise is alike across the slot's lights (lossless: 1).
5. **The score.** The variances are averaged over texels, channels and pairs as
   the score averages squared errors, with the score's peak:
   ``10 log10(peak² / mean variance)``.
"""

from __future__ import annotations

import numpy as np

from processing.btf import CompressedBTF
from processing.offline.btf import slot_table
from processing.offline.runner import frame_camera
from processing.registration import subgrid
from rig.archive import Archive
from rig.camera import PinholeCamera
from rig.config import RigConfig
from rig.geometry import texel_centers_mm
from sim.scene import NoiseParams
from sim.sensor import full_scale

__all__ = ["capture_gains", "floor_db", "leverage", "pixel_variance_dn", "texel_noise_gain"]


def pixel_variance_dn(signal_dn, *, bit_depth: int, noise: NoiseParams | None) -> np.ndarray:
    """Variance (DN²) of a pixel of noise-free signal ``signal_dn``: shot and read
    noise (``noise``; None: the scene lists no noise) and the quantisation's 1/12."""
    signal = np.clip(np.asarray(signal_dn, dtype=np.float64), 0.0, None)
    if noise is None:
        return np.full_like(signal, 1.0 / 12.0)
    gain = full_scale(bit_depth) / noise.full_well_e
    return signal * gain + (noise.read_noise_e * gain) ** 2 + 1.0 / 12.0


def _overlap(d: np.ndarray, filter: str) -> np.ndarray:
    """Phase-averaged Σ_p k(a − p)·k(b − p) of the pixel kernel k at offset d = b − a
    (pixels, one axis): the tent's autocorrelation (a cubic B-spline) for the box of
    bilinear samples; the unit box's (a triangle) for the area filter's nearest pixel."""
    d = np.abs(d)
    if filter == "area":
        return np.clip(1.0 - d, 0.0, None)
    near = 2.0 / 3.0 - d**2 + d**3 / 2.0
    far = np.clip(2.0 - d, 0.0, None) ** 3 / 6.0
    return np.where(d <= 1.0, near, far)


def texel_noise_gain(
    camera: PinholeCamera, sample_mm: float, size: int, *, filter: str = "box",
    max_supersample: int = 8,
) -> np.ndarray:  # fmt: skip
    """(size, size) Σ w_p²: a texel's noise variance over its pixels' (1 / the number of
    independent pixels it averages), for a frame of ``camera`` (sample frame, the
    btf stage's ``frame_camera``) rectified with ``filter`` (``rectify``'s).

    The texel's s_x × s_y sub-samples sit at offsets J·δ pixels from its centre (J:
    the texel step's 2 × 2 Jacobian, by projecting its neighbours; lens distortion
    is left out); each takes its pixels with the kernel k, so
    Σ w_p² = (1/S²) Σ_{k,l} K(J(δ_k − δ_l)), K the phase-averaged overlap of
    :func:`_overlap` per pixel axis.
    """
    step = sample_mm / size
    centres = texel_centers_mm(sample_mm, size).reshape(-1, 2)
    shift = np.array([[step, 0.0], [0.0, step]])
    plate = np.concatenate([centres, centres + shift[0], centres + shift[1]])
    pixels = camera.project(np.column_stack([plate, np.zeros(len(plate))]))[0]
    n = len(centres)
    along_x, along_y = pixels[n : 2 * n] - pixels[:n], pixels[2 * n :] - pixels[:n]
    largest = (float(np.linalg.norm(along_x, axis=1).max()),
               float(np.linalg.norm(along_y, axis=1).max()))  # fmt: skip
    sx, sy = subgrid(largest, filter=filter, max_supersample=max_supersample)
    # the differences of two sub-samples' offsets, in sub-sample steps, and how many pairs
    di, dj = np.meshgrid(np.arange(1 - sx, sx), np.arange(1 - sy, sy), indexing="ij")
    pairs = ((sx - np.abs(di)) * (sy - np.abs(dj))).ravel() / (sx * sy) ** 2
    frac = np.column_stack([di.ravel() / sx, dj.ravel() / sy])  # (m, 2) texel steps
    gain = np.empty(n)
    chunk = max(1, (1 << 20) // len(pairs))  # texels at a time: 2²⁰ offsets, 16 MB
    for start in range(0, n, chunk):
        sl = slice(start, start + chunk)
        offsets = frac[None, :, :1] * along_x[sl, None, :] + frac[None, :, 1:] * along_y[sl, None]
        kernel = _overlap(offsets[..., 0], filter) * _overlap(offsets[..., 1], filter)
        gain[sl] = kernel @ pairs
    return gain.reshape(size, size)


def leverage(btf: CompressedBTF, pairs, components: int) -> np.ndarray:
    """(pairs,) the share P_ll of light l's noise that the per-view PCA at c keeps, at
    each (view slot, light) pair: 1/L (the slot's mean over its L lights) plus the
    squared entries of light l's row in an orthonormal basis of the first min(c, rank)
    weight columns (each column is a left singular vector, scaled with its basis)."""
    out = []
    for j, light in pairs:
        lights = btf.weights.shape[1]
        kept = int(min(components, btf.rank[j]))
        q = np.linalg.qr(btf.weights[j, :, :kept].astype(np.float64))[0] if kept else None
        share = 1.0 / lights + (float(np.sum(q[light] ** 2)) if kept else 0.0)
        out.append(min(1.0, share))
    return np.array(out)


def floor_db(
    truth: np.ndarray, gains: np.ndarray, *, scale: float, exposure_s, bit_depth: int,
    noise: NoiseParams | None, peak: float, channels: int = 3, kept=None,
) -> float:  # fmt: skip
    """The PSNR (dB) of a score whose only error is the sensor's noise.

    truth : (pairs, N, N, 3) the noise-free truth the score compares with, ``btf_truth`` units
    gains : (pairs, N, N) :func:`texel_noise_gain` of each pair's frame
    scale : stored value per unit of truth (``irradiance_scale``)
    exposure_s, bit_depth, noise : the frames' exposure (s, one or one per pair) and the
        sensor (``noise`` None: quantisation alone)
    peak : the score's peak, ``btf_truth`` units
    channels : the camera's; a one-channel camera records the mean of the three
    kept : (pairs,) :func:`leverage` of the compressed model; None: lossless
    """
    exposure = np.asarray(exposure_s, dtype=np.float64).reshape(-1, 1, 1, 1)
    to_dn = scale * full_scale(bit_depth) * exposure
    signal = np.asarray(truth, dtype=np.float64)
    if channels == 1:
        signal = np.broadcast_to(signal.mean(axis=-1, keepdims=True), signal.shape)
    variance = pixel_variance_dn(signal * to_dn, bit_depth=bit_depth, noise=noise) / to_dn**2
    variance = variance * np.asarray(gains, dtype=np.float64)[..., None]
    if kept is not None:
        variance = variance * np.asarray(kept, dtype=np.float64)[:, None, None, None]
    return float(10.0 * np.log10(peak**2 / variance.mean()))


def capture_gains(
    archive_path, pairs, *, size: int, filter: str = "box"
) -> tuple[np.ndarray, np.ndarray]:
    """(pairs, size, size) :func:`texel_noise_gain` of the frame behind each (view slot,
    light) pair of the archive's BTF, from the model of the camera that took it, and
    (pairs,) the frames' exposures (s)."""
    with Archive.open(archive_path, mode="r") as archive:
        config = RigConfig.model_validate(archive.rig_config)
        table = slot_table(archive)
        records = {s.index: s for s in archive.step_table()}
        gains, exposures = [], []
        for j, light in pairs:
            record, camera = records[int(table.steps[j, light])], str(table.cameras[j, light])
            turntable = record.actuators.get("turntable_deg", 0.0)
            lens = frame_camera(archive, config, camera, turntable)
            gains.append(texel_noise_gain(lens, config.holder.sample_mm, size, filter=filter))
            exposures.append(record.exposures_s[0])
    return np.stack(gains), np.array(exposures, dtype=np.float64)
