"""Per-pixel photometric stereo for distant and near lamps (Woodham 1980).

For each pixel the Lambertian model ``I_l = s_l · b`` with ``b = ρ n`` is
solved in the (weighted) least-squares sense from L ≥ 3 observations. Images
are processed in chunks of pixels, converted to float64 one chunk at a time so
the stack is read from memory once and the arithmetic stays in cache.

References
----------
.. [1] Woodham, R. J. "Photometric method for determining surface orientation
   from multiple images." Optical Engineering 19(1), 1980.
.. [2] Seed ``004``: VirTex, photometric stereo for textile capture (albedo
   and scaled normal from the inverted light matrix, Eq. 3-4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._block import solve_block
from ._errors import PhotometricError
from ._fast import PinvRoute
from ._inputs import Stack, check_mask, check_stack
from ._lights import DistantLights, NearLights, PixelGrid, light_set_condition
from ._result import CONDITION_CAP, PhotometricResult, Reason

METHODS = ("lsq", "threshold", "irls")
DEFAULT_METHOD = "irls"
DEFAULT_MAX_CONDITION = 100.0
_CHUNK_BYTES = 6 << 20


@dataclass(frozen=True)
class _Options:
    method: str
    dark_level: float
    max_condition: float
    shadow_fraction: float
    highlight_fraction: float
    irls_iterations: int


def solve(
    images: np.ndarray,
    lights: DistantLights | NearLights,
    *,
    pixels: PixelGrid | np.ndarray | None = None,
    mask: np.ndarray | None = None,
    method: str = DEFAULT_METHOD,
    dark_level: float = 0.0,
    saturation_level: float | None = None,
    max_condition: float = DEFAULT_MAX_CONDITION,
    shadow_fraction: float = 0.05,
    highlight_fraction: float = 0.1,
    irls_iterations: int = 3,
    chunk_pixels: int | None = None,
) -> PhotometricResult:
    """Normals and albedo of one view from its images under L lamps.

    Parameters
    ----------
    images : (L, H, W) or (L, H, W, 3) uint8, uint16, float32 or float64
        One image per lamp. Integers are normalised by their dtype maximum;
        floats (e.g. HDR radiance) are used as they are.
    lights : DistantLights or NearLights
        The lamps, in the order of ``images``.
    pixels : PixelGrid or (H, W, 3) array_like, optional
        Required with :class:`NearLights`: where each pixel lies in the sample
        frame, mm (a grid on z = 0, or explicit positions, e.g. lifted by an
        estimated height). Not allowed with :class:`DistantLights`.
    mask : (H, W) bool, optional
        Pixels to solve; the rest get ``Reason.MASKED``. Integer masks of
        0 and 1, or 0 and the dtype maximum (0/255 in uint8), are accepted.
        The chosen pixels are packed, so a sparse mask costs its pixels.
    method : {"irls", "threshold", "lsq"}
        ``"lsq"`` uses every unsaturated observation; ``"threshold"`` and
        ``"irls"`` (the default: about half the error of ``"threshold"`` with
        shadows, highlights and noise, at several times the cost; see
        ``docs/photometric.md``) also reject shadowed and highlight
        observations per pixel.
    dark_level : float
        Normalised level at or below which a pixel's brightest observation
        counts as no signal (``Reason.DARK``).
    saturation_level : float, (L,) or (L, 3) array_like, optional
        Normalised level at or above which an observation is clipped and not
        used: one for all, one per light, or one per light and colour channel
        (a clipped channel drops the observation). Compared with the stored
        values, before any division by lamp colour. Default: 1.0 (full
        scale) for integer images, none for floats.
    max_condition : float
        Largest condition number accepted for a pixel's light system (full
        set → ``COPLANAR_LIGHTS``, set used → ``ILL_CONDITIONED``).
    shadow_fraction, highlight_fraction : float
        Robust methods: observations below ``shadow_fraction`` × the
        pixel's reference level are shadows; the brightest
        ``highlight_fraction`` of the lamps set that reference (and are
        dropped by ``"threshold"``).
    irls_iterations : int
        Reweighting steps of ``"irls"``.
    chunk_pixels : int, optional
        Pixels per chunk (memory bound); chosen from L and C by default.

    Returns
    -------
    PhotometricResult
        float32 maps, never NaN or inf; see :class:`Reason` for the flags.

    Raises
    ------
    PhotometricError
        Malformed input: wrong type, dtype or shape, mismatched light count,
        bad option values, non-finite float images.

    Examples
    --------
    >>> import numpy as np
    >>> dirs = np.array([[0.5, 0, 0.866], [-0.25, 0.433, 0.866], [-0.25, -0.433, 0.866]])
    >>> images = np.full((3, 2, 2), 0.866 * 0.5)      # a flat patch, albedo 0.5
    >>> result = solve(images, DistantLights(dirs), method="lsq")
    >>> np.round(result.normals[0, 0], 6).tolist(), round(float(result.albedo[0, 0]), 4)
    ([0.0, 0.0, 1.0], 0.5)
    """
    if not isinstance(lights, DistantLights | NearLights):
        raise PhotometricError(
            f"lights: expected DistantLights or NearLights, got {type(lights).__name__}"
        )
    stack = check_stack(images, lights.n_lights, saturation_level, lights.colour_balance())
    options = _check_options(
        method,
        dark_level,
        max_condition,
        shadow_fraction,
        highlight_fraction,
        irls_iterations,
    )
    selected = check_mask(mask, stack.shape)
    points = _pixel_points(lights, pixels, stack.shape)
    n_pixels = stack.shape[0] * stack.shape[1]
    out = _allocate(n_pixels, stack.channels)
    chunk = chunk_pixels or max(256, _CHUNK_BYTES // (8 * lights.n_lights * stack.channels))
    if points is not None:
        chunk = max(64, chunk // 4)  # per-pixel light vectors take 3× the memory
    shared_condition = light_matrix = route = None
    if isinstance(lights, DistantLights):
        light_matrix = lights.light_matrix()
        shared_condition = min(light_set_condition(light_matrix), CONDITION_CAP)
        if options.method == "lsq" and shared_condition <= options.max_condition:
            route = PinvRoute.prepare(light_matrix, shared_condition, stack, options.dark_level)
            flat_out = _route_view(out, stack.channels)
    for index in _chunks(n_pixels, chunk, selected):
        if route is not None:
            pixel = _pixel_ids(index)
            if isinstance(index, slice) and stack.values.flags.c_contiguous:
                hard = route.solve(stack.values, index.start, pixel.size, pixel, flat_out)
            else:  # the masked pixels, or a chunk of a strided stack (a crop), packed
                packed = np.ascontiguousarray(stack.values[:, index])
                hard = route.solve(packed, 0, pixel.size, pixel, flat_out)
            if not hard.any():
                continue
            index = pixel[hard]
        chunk_in = _read_chunk(stack, index, options.dark_level)
        if points is None:
            block = solve_block(*chunk_in, light_matrix, shared_condition, options)
        else:
            block = solve_block(*chunk_in, lights.light_vectors(points[index]), None, options)
        _store(out, index, block)
    h, w = stack.shape
    albedo_shape = (h, w) if stack.channels == 1 else (h, w, 3)
    return PhotometricResult(
        normals=out["normals"].reshape(h, w, 3),
        albedo=out["albedo"].reshape(albedo_shape),
        valid=(out["reason"] == Reason.OK).reshape(h, w),
        reason=out["reason"].reshape(h, w),
        condition=out["condition"].reshape(h, w),
        residual=out["residual"].reshape(h, w),
        lights_used=out["lights_used"].reshape(h, w),
    )


def _check_options(
    method,
    dark_level,
    max_condition,
    shadow_fraction,
    highlight_fraction,
    irls_iterations,
) -> _Options:
    if method not in METHODS:
        raise PhotometricError(f"method: {method!r} is not one of {', '.join(METHODS)}")
    if not (np.isfinite(dark_level) and dark_level >= 0):
        raise PhotometricError(f"dark_level: expected a finite level ≥ 0, got {dark_level!r}")
    if not (np.isfinite(max_condition) and max_condition >= 1):
        raise PhotometricError(
            f"max_condition: expected a finite number ≥ 1, got {max_condition!r}"
        )
    if not 0 <= shadow_fraction < 1:
        raise PhotometricError(f"shadow_fraction: expected 0 ≤ value < 1, got {shadow_fraction!r}")
    if not 0 <= highlight_fraction < 1:
        raise PhotometricError(
            f"highlight_fraction: expected 0 ≤ value < 1, got {highlight_fraction!r}"
        )
    if int(irls_iterations) != irls_iterations or irls_iterations < 1:
        raise PhotometricError(f"irls_iterations: expected an integer ≥ 1, got {irls_iterations!r}")
    return _Options(
        method,
        float(dark_level),
        float(max_condition),
        float(shadow_fraction),
        float(highlight_fraction),
        int(irls_iterations),
    )


def _pixel_points(lights, pixels, shape) -> np.ndarray | None:
    if isinstance(lights, DistantLights):
        if pixels is not None:
            raise PhotometricError(
                "pixels: only used with NearLights; distant lights shine alike on every pixel"
            )
        return None
    if pixels is None:
        raise PhotometricError(
            "pixels: NearLights need the pixel positions, a PixelGrid or an (H, W, 3) array in mm"
        )
    if isinstance(pixels, PixelGrid):
        if pixels.shape != shape:
            raise PhotometricError(f"pixels: grid shape {pixels.shape} ≠ image size {shape}")
        positions = pixels.positions_mm()
    else:
        positions = np.asarray(pixels, dtype=np.float64)
        if positions.shape != (*shape, 3):
            raise PhotometricError(
                f"pixels: expected positions of shape {(*shape, 3)} (mm), got {positions.shape}"
            )
        if not np.all(np.isfinite(positions)):
            raise PhotometricError("pixels: positions must be finite")
    points = positions.reshape(-1, 3)
    lowest_lamp = float(lights.positions_mm[:, 2].min())
    if points[:, 2].max() >= lowest_lamp:
        raise PhotometricError(
            f"pixels: a pixel at z = {points[:, 2].max():.4g} mm is not below the lowest lamp "
            f"(z = {lowest_lamp:.4g} mm)"
        )
    return points


def _chunks(n_pixels: int, chunk: int, selected: np.ndarray | None):
    """Ranges of ``chunk`` pixels; with a mask, the selected pixels packed ``chunk`` at a time."""
    if selected is None:
        for start in range(0, n_pixels, chunk):
            yield slice(start, min(start + chunk, n_pixels))
        return
    chosen = np.flatnonzero(selected)
    for start in range(0, chosen.size, chunk):
        yield chosen[start : start + chunk]


def _pixel_ids(index) -> np.ndarray:
    return np.arange(index.start, index.stop) if isinstance(index, slice) else index


def _route_view(out: dict[str, np.ndarray], channels: int) -> tuple:
    """The result arrays in the order and shapes the pseudo-inverse route writes."""
    albedo = out["albedo"].reshape(-1, channels)
    names = ("reason", "condition", "residual", "lights_used")
    return (out["normals"], albedo, *(out[name] for name in names))


def _store(out: dict[str, np.ndarray], index, block: dict) -> None:
    for name, values in block.items():
        out[name][index] = values


def _allocate(n_pixels: int, channels: int) -> dict[str, np.ndarray]:
    normals = np.zeros((n_pixels, 3), np.float32)
    normals[:, 2] = 1.0
    return {
        "normals": normals,
        "albedo": np.zeros((n_pixels,) if channels == 1 else (n_pixels, 3), np.float32),
        "reason": np.full(n_pixels, Reason.MASKED, np.uint8),
        "condition": np.zeros(n_pixels, np.float32),
        "residual": np.zeros(n_pixels, np.float32),
        "lights_used": np.zeros(n_pixels, np.uint16),
    }


def _read_chunk(stack: Stack, index, dark_level: float):
    """One chunk's observations as the per-pixel route takes them.

    Returns ``(obs, energy, dark, clipped)``: normalised float64 observations
    (L, n[, C]) divided by the lamps' colour balance, Σ I² per pixel (and
    channel), whether the brightest stored observation (mean over channels of
    each channel's maximum) is at or below ``dark_level``, and the
    observations at or above their clipping level in any channel ((L, n)
    bool, or None when none is). Levels are compared with the stored values,
    as the pseudo-inverse route does.
    """
    raw = stack.values[:, index]
    colour = raw.ndim == 3
    peak = raw.max(axis=0)
    brightest = peak.mean(axis=1) if colour else peak
    dark = brightest <= dark_level / stack.scale
    clipped = None
    if stack.clips:
        level = stack.clip_raw[:, None, :] if colour else stack.clip_raw
        hit = raw >= level
        if hit.any():
            clipped = hit.any(axis=2) if colour else hit
    obs = raw * (stack.gain[:, None, :] if colour else stack.gain)
    energy = np.einsum("ln...,ln...->n...", obs, obs)
    # A NaN or ±inf anywhere makes Σ I² non-finite: one check, no extra pass.
    if not np.all(np.isfinite(energy)):
        bad = ~np.isfinite(obs)
        if not bad.any():
            raise PhotometricError(
                "images: values above 1e154 overflow the least-squares sums; rescale the images"
            )
        light, column = (int(i) for i in np.argwhere(bad)[0][:2])
        pixel = index.start + column if isinstance(index, slice) else int(index[column])
        row, col = divmod(pixel, stack.shape[1])
        raise PhotometricError(
            f"images[{light}] has a non-finite value at pixel (row {row}, column {col}); "
            "float images must be finite (exclude bad pixels with the mask instead)"
        )
    return obs, energy, dark, clipped
