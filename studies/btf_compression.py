"""``rig bench btf``: what each compression level costs in accuracy, time and space.

Everything runs on :class:`~processing.btf.synthetic.SyntheticBTF` over the H2
sampling (81 views × 81 lights), in one process, so the times are comparable
with each other (ratios), not across machines.
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np
from matplotlib.figure import Figure

from processing.btf import (
    compress_btf,
    compress_global_svd,
    compress_view,
    compress_view_svd,
    light_weights,
    psnr_db,
    reconstruct,
    rmse,
)
from processing.btf.synthetic import SyntheticBTF
from rig.geometry import Sampling

__all__ = ["plot", "run"]


def _best_of(repeats: int, fn) -> tuple[float, object]:
    best, result = np.inf, None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - start)
    return best, result


def _all_rmse(model, reference: np.ndarray, *, timed: int = 200) -> tuple[float, float]:
    """RMSE over every measured (view, light) image, and the mean time of one
    :func:`reconstruct` call over ``timed`` random (view, light) pairs."""
    n_views, n_lights = reference.shape[:2]
    squared = 0.0
    for v in range(n_views):
        diff = model.reconstruct_view(v).astype(np.float64) - reference[v]
        squared += float(np.sum(diff**2))
    pairs = np.random.default_rng(0).integers(0, [n_views, n_lights], size=(timed, 2))
    start = time.perf_counter()
    for v, li in pairs:
        reconstruct(model, view=int(v), light=int(li))
    per_texture = (time.perf_counter() - start) / timed
    return float(np.sqrt(squared / reference.size)), per_texture


def _held_out_lights(sampling: Sampling, every: int) -> np.ndarray:
    """Every ``every``-th light strictly inside the hemisphere's outer ring (inside the hull)."""
    theta = sampling.directions[:, 0]
    inner = np.flatnonzero((theta > 0) & (theta < theta.max()))
    return inner[::every]


def run(
    quick: bool = False,
    *,
    size: int | None = None,
    components: tuple[int, ...] = (1, 2, 4, 8, 16, 32),
    svd_components: tuple[int, ...] = (4, 16),
    speed_size: int | None = None,
    memory_size: int | None = None,
    held_out_every: int = 4,
    repeats: int | None = None,
) -> list[dict]:
    """Rows of the BTF benchmark table (each a dict with a ``"row"`` kind).

    Parameters
    ----------
    quick : bool
        The sizes and repeats not given: 32, 64, 64 and 1 (else 64, 256, 256 and 3).
    size : int
        Normtexture size for the accuracy rows (81 × 81 images of size²).
    components : tuple of int
        c values of the per-view PCA.
    svd_components : tuple of int
        c values of the global SVD (seed 001 keeps 4).
    speed_size : int
        Size of the single-view PCA timed against ``numpy.linalg.svd``.
    memory_size : int
        Size of the full 81 × 81 BTF whose streaming compression is traced
        for peak memory (0 skips it).
    held_out_every : int
        Every k-th inner light is left out for the interpolation rows.
    repeats : int
        Timings are the best of this many runs.

    Returns
    -------
    list of dict
        ``row = "pca" | "svd"``: components, rmse, psnr_db, storage_ratio,
        compress_s, reconstruct_ms; ``row = "interpolation"``: method, rmse,
        psnr_db (held-out lights, against the true images); ``row = "speed"``:
        gram_s, numpy_svd_s, speedup, rmse of both; ``row = "memory"``:
        peak_mib, output_mib, input_mib.
    """
    size = size or (32 if quick else 64)
    speed_size = speed_size or (64 if quick else 256)
    memory_size = (64 if quick else 256) if memory_size is None else memory_size
    repeats = repeats or (1 if quick else 3)
    h2 = Sampling.named("H2")
    dirs = h2.directions
    source = SyntheticBTF(size, dirs, dirs)
    reference = np.asarray(source)  # (81, 81, N, N, 3) float32
    peak = float(reference.max())
    raw_bytes = reference.nbytes
    rows: list[dict] = []
    for row, compress, counts in (
        ("pca", compress_btf, components), ("svd", compress_global_svd, svd_components)
    ):
        for c in counts:
            t, model = _best_of(
                1,
                lambda c=c, compress=compress: compress(
                    reference, view_dirs_deg=dirs, light_dirs_deg=dirs, components=c
                ),
            )
            err, per_texture = _all_rmse(model, reference)
            rows.append({
                "row": row, "components": c, "rmse": err, "psnr_db": psnr_db(err, peak=peak),
                "storage_ratio": raw_bytes / model.nbytes, "compress_s": t,
                "reconstruct_ms": per_texture * 1e3,
            })  # fmt: skip

    # Interpolation at held-out lights: compress without them, predict them.
    held = _held_out_lights(h2, held_out_every)
    kept = np.setdiff1d(np.arange(len(dirs)), held)
    model = compress_btf(
        reference[:, kept], view_dirs_deg=dirs, light_dirs_deg=dirs[kept], components=16
    )
    for method in ("nearest", "nearest4", "barycentric"):
        weights = [light_weights(model.light_vectors, dirs[li], method=method) for li in held]
        squared = 0.0
        for v in range(len(dirs)):
            for li, (idx, w) in zip(held, weights, strict=True):
                guess = model.blend([v], [1.0], idx, w)
                squared += float(np.sum((guess.astype(np.float64) - reference[v, li]) ** 2))
        err = float(np.sqrt(squared / (len(dirs) * len(held) * reference[0, 0].size)))
        rows.append({
            "row": "interpolation", "method": method, "held_out_lights": len(held),
            "rmse": err, "psnr_db": psnr_db(err, peak=peak),
        })  # fmt: skip

    # Per-view PCA through the Gram matrix against numpy.linalg.svd, same matrix.
    view_stack = SyntheticBTF(speed_size, dirs, dirs)[len(dirs) // 2]
    gram_s, fast = _best_of(repeats, lambda: compress_view(view_stack, components=16))
    svd_s, slow = _best_of(repeats, lambda: compress_view_svd(view_stack, components=16))

    def slot_rmse(slot) -> float:
        recon = slot.mean.astype(np.float64) + np.einsum(
            "lk,kyxc->lyxc", slot.weights.astype(np.float64), slot.basis.astype(np.float64)
        )
        return rmse(recon, view_stack)

    rows.append({
        "row": "speed", "size": speed_size, "lights": len(dirs), "components": 16,
        "gram_s": gram_s, "numpy_svd_s": svd_s, "speedup": svd_s / gram_s,
        "gram_rmse": slot_rmse(fast), "numpy_svd_rmse": slot_rmse(slow),
    })  # fmt: skip

    if memory_size:
        lazy = SyntheticBTF(memory_size, dirs, dirs)
        tracemalloc.start()
        try:
            model = compress_btf(lazy, view_dirs_deg=dirs, light_dirs_deg=dirs, components=16)
            _, peak_bytes = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
        mib = 1 << 20
        rows.append({
            "row": "memory", "size": memory_size, "views": len(dirs), "lights": len(dirs),
            "components": 16, "peak_mib": peak_bytes / mib, "output_mib": model.nbytes / mib,
            "input_mib": 4 * np.prod(lazy.shape) / mib,
        })  # fmt: skip
    return rows


def plot(rows: list[dict], path) -> None:
    """Write the accuracy–storage–time plot of ``docs/btf.md`` (PNG) from :func:`run` rows.

    Left: RMSE against the storage ratio for the per-view PCA (c labelled) and
    the global SVD; right: RMSE at held-out lights per interpolation method.
    """
    fig = Figure(figsize=(10, 3.8))
    ax0, ax1 = fig.subplots(1, 2, gridspec_kw={"width_ratios": [2, 1]})
    for kind, marker, label in (("pca", "o-", "per-view PCA"), ("svd", "s--", "global SVD")):
        sel = [r for r in rows if r["row"] == kind]
        if not sel:
            continue
        ratio = [r["storage_ratio"] for r in sel]
        ax0.plot(ratio, [r["rmse"] for r in sel], marker, label=label)
        for r in sel:
            ax0.annotate(
                f"c={r['components']}, {r['compress_s']:.1f} s",
                (r["storage_ratio"], r["rmse"]), textcoords="offset points", xytext=(4, 4),
                fontsize=7,
            )  # fmt: skip
    ax0.set_xscale("log")
    ax0.set_yscale("log")
    ax0.set_xlabel("storage ratio (float32 normtextures / compressed)")
    ax0.set_ylabel("RMSE over all measured images")
    ax0.set_title("accuracy vs storage (labels: c, compression time)")
    ax0.legend(fontsize=8)
    interp = [r for r in rows if r["row"] == "interpolation"]
    ax1.bar([r["method"] for r in interp], [r["rmse"] for r in interp], color="tab:gray")
    ax1.set_ylabel("RMSE at held-out lights")
    ax1.set_title("light interpolation (c = 16)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
