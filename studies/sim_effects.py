"""`rig bench sim`: what each effect costs per frame, against plain Lambertian.

For each image size (square, the default rig's field of view) and each effect
alone, then all of them, the median time of a few frames is measured in the
same run as the no-effect Lambertian baseline; ``ratio`` = time / baseline.
``frame_ms`` renders a new view each time (GL pass + hit reconstruction);
``relit_ms`` re-lights a cached view (another lamp), the common case in a
session where every lamp fires at each position.
"""

from __future__ import annotations

import statistics
from time import perf_counter

from sim.scene import EFFECTS, scene_from_dict
from sim.simulator import Simulator

__all__ = ["run"]

_SPECULAR = {"model": "phong", "ks": 0.2, "exponent": 30.0}


def _scene(size: int, effects: tuple[str, ...], spp: int):
    cams = [
        {"id": "cam0", "theta_deg": 30.0, "width": size, "height": size,
         "fx_px": 3000.0 * size / 1024, "fy_px": 3000.0 * size / 1024}
    ]  # fmt: skip
    data = {
        "sample": {"generator": "weave", "materials": ["yarn"]},
        "materials": {"yarn": {"specular": _SPECULAR}},
        "rig": {"overrides": {"camera_arc": {"cameras": cams}}},
        "effects": list(effects),
    }
    if "lens_distortion" in effects:
        data["lens_distortion"] = {"coefficients": [-0.1, 0.02, 0.0, 0.0, 0.0]}
    if "interreflection" in effects:
        data["interreflection"] = {"samples_per_pixel": spp}
    return scene_from_dict(data)


def _frame_s(sim: Simulator, k: int, *, new_view: bool) -> float:
    tt = 0.37 * (k + 1) if new_view else 0.0  # a turntable angle not rendered before
    lamp = "lamp3" if new_view or k % 2 == 0 else "lamp5"
    t0 = perf_counter()
    sim.render_state("cam0", turntable_deg=tt, arc_deg=40.0, lamps_on=[lamp], laser=True)
    return perf_counter() - t0


def _paired(base: Simulator, sim: Simulator, runs: int, *, new_view: bool, first: int):
    """Median ms of ``sim`` and of ``base``, frames interleaved so load drifts cancel.

    ``first`` numbers the views so the long-lived baseline never reuses one.
    """
    t_base, t_case = [], []
    for k in range(first, first + runs + 1):  # the first pair warms caches
        t_base.append(_frame_s(base, k, new_view=new_view))
        t_case.append(_frame_s(sim, k, new_view=new_view))
    return statistics.median(t_case[1:]) * 1000, statistics.median(t_base[1:]) * 1000


def run(
    quick: bool = False,
    *,
    sizes: tuple[int, ...] = (256, 1024),
    effects: tuple[str, ...] = EFFECTS,
    runs: int = 5,
    interreflection_spp: int = 4,
) -> list[dict]:
    """Time per frame for each effect alone and all together, per image size.

    Returns one row per (size, case): ``size``, ``effects``, ``frame_ms``,
    ``relit_ms``, ``ratio`` (frame_ms / the Lambertian frame_ms measured
    interleaved with it), ``relit_ratio``. ``quick`` runs 64² and 256² with
    2 frames each.
    """
    if quick:
        sizes, runs = tuple(s // 4 for s in sizes), 2
    cases = [(), *((e,) for e in effects)] + ([tuple(effects)] if len(effects) > 1 else [])
    rows = []
    for size in sizes:
        with Simulator(_scene(size, (), interreflection_spp)) as base:
            for i, case in enumerate(cases):
                with Simulator(_scene(size, case, interreflection_spp)) as sim:
                    first = i * (runs + 1)
                    frame_ms, base_ms = _paired(base, sim, runs, new_view=True, first=first)
                    relit_ms, base_relit_ms = _paired(base, sim, runs, new_view=False, first=first)
                rows.append(
                    {
                        "size": f"{size}²",
                        "effects": "+".join(case) if case else "lambert (baseline)",
                        "frame_ms": frame_ms,
                        "ratio": frame_ms / base_ms,
                        "relit_ms": relit_ms,
                        "relit_ratio": relit_ms / base_relit_ms,
                    }
                )
    return rows
