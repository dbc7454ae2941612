"""``rig bench ps``: what photometric accuracy costs in time.

:func:`run` returns table rows (dicts) of three kinds:

``read``
    The floors, timed interleaved with the solves: one pass over the float32
    image stack (``stack.sum()``), a read with a conversion
    (``stack.astype(np.float32).sum()``), one product with the
    pseudo-inverse over the whole stack (``pinv(L) @ I``, what least squares
    cannot beat), and the masked pixels gathered and solved packed.
``solver`` / ``integrator``
    Seconds per megapixel for each method on the same stack, the least
    squares time as a ratio to the floors (``ratio_to_gemm``), each robust
    method's cost as a multiple of least squares, and the masked solve as a
    ratio to the packed one (``ratio_to_packed``).
``accuracy``
    Mean angular error against the number of lamps used, on a synthetic
    surface per scenario (see ``SCENARIOS``) and method;
    ``capture_time_s`` comes from a callable (the plan estimate).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from processing.photometric import (
    METHODS,
    DistantLights,
    NearLights,
    PixelGrid,
    integrate_normals,
    solve,
)
from rig.config import default_rig_config
from rig.plan import parse_plan
from rig.schedule import compile_plan

LAMP_COUNTS = (3, 4, 6, 12, 24, None)  # None: all lamps
#: Accuracy scenarios: Lambertian with noise (σ = 0.005, attached shadows
#: only), and with cast shadows (10 % of observations at 5 %), Blinn-Phong
#: highlights (strength 0.8, exponent 60) and the same noise.
SCENARIOS = ("noise", "shadows+specular+noise")
#: Share of pixels in the timed mask.
MASK_FRACTION = 0.05


def default_capture_time_s(lamps: int) -> float:
    """Seconds a photometric-stereo set of ``lamps`` lamps at θ = 45° takes on the
    default rig (the plan's estimate)."""
    plan = parse_plan(
        f'[sample]\nname = "bench"\n[captures.ps]\nlights = {{theta_deg = 45, count = {lamps}}}'
    )
    return compile_plan(plan, default_rig_config()).estimate.total_s


def run(
    quick: bool = False,
    *,
    n_lights: int = 96,
    size_px: int | None = None,
    robust_rows: int = 64,
    accuracy_px: int | None = None,
    lamp_counts=LAMP_COUNTS,
    repeats: int | None = None,
    capture_time_s: Callable[[int], float] = default_capture_time_s,
    seed: int = 0,
) -> list[dict]:
    """Time the solvers and integrators and measure accuracy against lamp count.

    Parameters
    ----------
    quick : bool
        The sizes and repeats not given: 256², 64² and 1 (else 1024², 128² and 3).
    n_lights, size_px : int
        The timed stack is (n_lights, size_px, size_px) float32.
    robust_rows : int
        Rows of that stack the slower solvers (robust, near) are timed on;
        their time is scaled to a megapixel.
    accuracy_px : int
        Side of the synthetic surface for the accuracy rows.
    lamp_counts : sequence of int or None
        Lamp counts for the accuracy rows (None: all ``n_lights``).
    repeats : int
        Best-of repeats for each timing.
    capture_time_s : callable
        ``capture_time_s(n_lamps) -> seconds`` fills the column of that name
        (by default the estimate of such a capture on the default rig).
    """
    size_px = size_px or (256 if quick else 1024)
    accuracy_px = accuracy_px or (64 if quick else 128)
    repeats = repeats or (1 if quick else 3)
    rng = np.random.default_rng(seed)
    stack = rng.random((n_lights, size_px, size_px), dtype=np.float32)
    lights = DistantLights(lamp_layout(n_lights))
    mpx = size_px * size_px / 1e6
    flat = stack.reshape(n_lights, -1)
    pinv = np.linalg.pinv(lights.light_matrix()).astype(np.float32)
    mask = rng.random(stack.shape[1:]) < MASK_FRACTION
    part = stack[:, :robust_rows]
    part_mpx = part.shape[1] * part.shape[2] / 1e6
    near = NearLights(lights.directions * 500.0)
    grid = PixelGrid(part.shape[1:], 0.05)
    # The first call of a compiled route compiles it, or loads it from numba's cache:
    # a cost per process and dtype, not per solve (docs/photometric.md), so it is paid here.
    for method in METHODS:
        solve(part[:, :4, :4], lights, method=method)
    solve(part[:, :4, :4], near, pixels=PixelGrid((4, 4), 0.05), method="lsq")
    # Everything interleaved, best of `repeats`: drifting load hits floors and solves alike.
    # The slower solvers run on `part` and are compared with lsq on the same rows.
    timed = _best_interleaved(
        {
            "sum": lambda: stack.sum(),
            "astype_sum": lambda: stack.astype(np.float32).sum(),
            "gemm": lambda: pinv @ flat,
            "lsq": lambda: solve(stack, lights, method="lsq"),
            "masked": lambda: solve(stack, lights, method="lsq", mask=mask),
            "packed": lambda: solve(stack[:, mask][..., None], lights, method="lsq"),
            "part lsq": lambda: solve(part, lights, method="lsq"),
            **{m: lambda m=m: solve(part, lights, method=m) for m in METHODS if m != "lsq"},
            "near lsq": lambda: solve(part, near, pixels=grid, method="lsq"),
        },
        repeats,
    )
    lsq_s = timed["lsq"] / mpx
    rows = [
        {"kind": "read", "name": "stack.sum()", "seconds_per_mpx": timed["sum"] / mpx},
        {
            "kind": "read",
            "name": "stack.astype(float32).sum()",
            "seconds_per_mpx": timed["astype_sum"] / mpx,
        },
        {"kind": "read", "name": "pinv(L) @ I (one GEMM)", "seconds_per_mpx": timed["gemm"] / mpx},
        {
            "kind": "solver",
            "name": "lsq",
            "seconds_per_mpx": lsq_s,
            "ratio_to_sum": timed["lsq"] / timed["sum"],
            "ratio_to_astype_sum": timed["lsq"] / timed["astype_sum"],
            "ratio_to_gemm": timed["lsq"] / timed["gemm"],
            "cost_vs_lsq": 1.0,
        },
        {
            "kind": "read",
            "name": f"stack[:, mask] + lsq of those ({MASK_FRACTION:.0%} of pixels)",
            "seconds_per_mpx": timed["packed"] / mpx,
        },
        {
            "kind": "solver",
            "name": f"lsq, {MASK_FRACTION:.0%} mask",
            "seconds_per_mpx": timed["masked"] / mpx,
            "ratio_to_packed": timed["masked"] / timed["packed"],
        },
    ]
    for name in (*(m for m in METHODS if m != "lsq"), "near lsq"):
        cost = timed[name] / timed["part lsq"]
        rows.append(
            {
                "kind": "solver",
                "name": name,
                "seconds_per_mpx": timed[name] / part_mpx,
                "ratio_to_gemm": cost * timed["lsq"] / timed["gemm"],
                "cost_vs_lsq": cost,
            }
        )
    rows.extend(_integrator_rows(size_px, repeats))
    rows.extend(_accuracy_rows(n_lights, accuracy_px, lamp_counts, capture_time_s, rng))
    return rows


def lamp_layout(n: int) -> np.ndarray:
    """n lamp directions on three rings (θ = 20°, 40°, 60°), spread in azimuth: (n, 3)."""
    rings = (20.0, 40.0, 60.0) if n >= 6 else (35.0,) if n < 5 else (30.0, 55.0)
    counts = np.diff(np.linspace(0, n, len(rings) + 1).round().astype(int))
    dirs = []
    for k, (theta, count) in enumerate(zip(rings, counts, strict=True)):
        phi = np.deg2rad(k * 30.0 + 360.0 * np.arange(count) / count)
        t = np.deg2rad(theta)
        dirs.append(
            np.column_stack(
                [np.sin(t) * np.cos(phi), np.sin(t) * np.sin(phi), np.full(count, np.cos(t))]
            )
        )
    return np.concatenate(dirs)


def _integrator_rows(size_px: int, repeats: int) -> list[dict]:
    side = min(size_px, 512)
    y, x = np.mgrid[0:side, 0:side] / side
    normals = np.stack([0.2 * np.sin(6 * x), 0.1 * np.cos(5 * y), np.ones_like(x)], axis=-1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    mpx = side * side / 1e6
    rows = []
    for method in ("dct", "fc", "lsq"):
        seconds = _best(
            lambda m=method: integrate_normals(normals, pitch_mm=0.1, method=m), repeats
        )
        rows.append(
            {
                "kind": "integrator",
                "name": method,
                "seconds_per_mpx": seconds / mpx,
                "size_px": side,
            }
        )
    return rows


def _accuracy_rows(n_lights, side, lamp_counts, capture_time_s, rng) -> list[dict]:
    y, x = (np.mgrid[0:side, 0:side] - side / 2) / side
    h = 0.0
    hx = np.zeros_like(x)
    hy = np.zeros_like(x)
    for _ in range(8):  # Gaussian bumps, slopes up to ~30°
        cx, cy, s, a = rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(0.05, 0.1), 0.03
        g = a * rng.choice([-1, 1]) * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * s * s))
        h = h + g
        hx -= g * (x - cx) / (s * s)
        hy -= g * (y - cy) / (s * s)
    truth = np.stack([-hx, -hy, np.ones_like(hx)], axis=-1)
    truth /= np.linalg.norm(truth, axis=-1, keepdims=True)
    albedo = rng.uniform(0.3, 0.8, (side, side))
    rows = []
    for count in lamp_counts:
        n = n_lights if count is None else int(count)
        dirs = lamp_layout(n)
        lambert = np.clip(np.einsum("li,hwi->lhw", dirs, truth), 0, None)
        half = dirs + np.array([0.0, 0.0, 1.0])
        half /= np.linalg.norm(half, axis=1, keepdims=True)
        gloss = 0.8 * np.clip(np.einsum("li,hwi->lhw", half, truth), 0, None) ** 60 * (lambert > 0)
        for scenario in SCENARIOS:
            images = albedo * lambert
            if scenario != "noise":
                images = images + gloss
                images[rng.random(images.shape) < 0.1] *= 0.05  # cast shadows
            images = images + rng.normal(0, 0.005, images.shape)
            images = np.clip(images, 0, None).astype(np.float32)
            for method in METHODS:
                result = solve(images, DistantLights(dirs), method=method)
                found = result.normals.astype(np.float64)
                sin = np.linalg.norm(np.cross(found, truth), axis=-1)
                err = np.degrees(np.arctan2(sin, np.sum(found * truth, axis=-1)))[result.valid]
                rows.append(
                    {
                        "kind": "accuracy",
                        "name": method,
                        "scenario": scenario,
                        "n_lamps": n,
                        "mean_angular_error_deg": float(err.mean()) if err.size else None,
                        "valid_fraction": float(result.valid.mean()),
                        "capture_time_s": capture_time_s(n),
                    }
                )
    return rows


def _best_interleaved(calls: dict[str, Callable[[], object]], repeats: int) -> dict[str, float]:
    best = dict.fromkeys(calls, np.inf)
    for _ in range(max(1, repeats)):
        for name, call in calls.items():
            best[name] = min(best[name], _best(call, 1))
    return best


def _best(call: Callable[[], object], repeats: int) -> float:
    best = np.inf
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        call()
        best = min(best, time.perf_counter() - start)
    return best
