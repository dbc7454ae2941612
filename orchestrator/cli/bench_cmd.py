"""`rig bench AREA`: what accuracy costs in time, measured against baselines
in the same run. Each area's benchmark lives with its code and returns rows."""

from __future__ import annotations

import importlib
import json
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from orchestrator.cli.common import PLAIN_HELP, console, quiet_dask_logs, working
from rig.config import default_rig_config
from rig.plan import parse_plan
from rig.schedule import compile_plan

__all__ = ["app", "markdown_table"]


def _archive(module, quick: bool) -> list[dict]:
    with tempfile.TemporaryDirectory(prefix="rig-bench-") as tmp:
        return module.run_bench(tmp, n_steps=8 if quick else 32, repeats=1 if quick else 3)


def _plain(module, quick: bool) -> list[dict]:
    return module.run_bench(quick=quick)


def _process(module, quick: bool) -> list[dict]:
    quiet_dask_logs()
    return module.run_bench(quick=quick)


def _ps(module, quick: bool) -> list[dict]:
    rig = default_rig_config()

    def capture_time_s(lamps: int) -> float:
        # What a photometric-stereo set of this many lamps costs on the default rig.
        plan = parse_plan(
            f'[sample]\nname = "bench"\n[captures.ps]\nlights = {{theta_deg = 45, count = {lamps}}}'
        )
        return compile_plan(plan, rig).estimate.total_s

    size = {"size_px": 256, "repeats": 1, "accuracy_px": 64} if quick else {}
    return module.run_bench(capture_time_s=capture_time_s, **size)


def _btf(module, quick: bool) -> list[dict]:
    sizes = {"size": 32, "speed_size": 64, "memory_size": 64, "repeats": 1} if quick else {}
    return module.run_bench(**sizes)


# area → (module, how to call its run_bench); imported when its command runs
AREAS: dict[str, tuple[str, Callable]] = {
    "archive": ("rig.archive.bench", _archive),
    "daemon": ("orchestrator.daemon_bench", _plain),
    "process": ("orchestrator.process_bench", _process),
    "sim": ("sim.bench", _plain),
    "ps": ("processing.photometric.bench", _ps),
    "btf": ("processing.btf.bench", _btf),
    "mdf": ("processing.mdf.bench", _plain),
    "calibration": ("orchestrator.calibration_bench", _plain),
    "radiometry": ("orchestrator.radiometry_bench", _plain),
    "render": ("render.bench", _plain),
    "render-loop": ("orchestrator.render_loop", _plain),
    "error-budget": ("orchestrator.error_budget", _plain),
    "silhouettes": ("orchestrator.silhouettes", _plain),
    "environment": ("render.env_bench", _plain),
}

# what each area measures and what its table prints (its command's help)
HELP = {
    "archive": "Append throughput of the session archive in raw frame MB/s, per method and "
    "frame content, against plain file writes in the same run and the seed rig's 141.6 MB/s "
    "of laser-scan frames; prints the median, min and max MB/s, the ratio to raw writes "
    "and the compression.",
    "daemon": "The daemon's own cost: a session through the real daemon, sockets, archive "
    "and workers against a modelled rig in virtual time; prints per session size and "
    "worker count the wall time over the modelled hardware time (goal under 2 %) and "
    "frames/s.",
    "process": "Items/s of `rig process --stages ps` on a simulated session against Dask "
    "workers (1, 2, all cores; threads and worker processes) and --size; prints the "
    "speed-up against one worker in the same run and where the time goes.",
    "sim": "What each simulator effect costs per frame: ms per new view and per re-lit "
    "view, for each effect alone and all together, per image size, as a ratio to plain "
    "Lambertian frames drawn in the same run.",
    "ps": "What photometric-stereo accuracy costs in time: seconds per megapixel of each "
    "solver and integrator beside the floor of one pass over the image stack, and the "
    "normal and height error against lamp count beside each set's capture time.",
    "btf": "What each BTF compression level costs: per-view PCA and global SVD at each "
    "number of components c, their error on held-out images, compression time, size "
    "and peak memory, on a synthetic H2 BTF.",
    "mdf": "What MDF accuracy costs in capture and compute time: frames/s of the "
    "space-time peak detectors beside the floor of one pass over the frames, and the "
    "height error against scan locations and sweep step beside each scan's capture time.",
    "calibration": "Calibration error against the simulator's truth and what it costs: "
    "reprojection, focal-length and camera-centre error against the number of turntable "
    "poses, laser-sheet angle error against target heights, beside each session's "
    "capture time.",
    "radiometry": "What the response curve and lamp flat fields buy in processing: "
    "photometric-stereo normal and albedo error and BTF error of a simulated sample with "
    "a gamma camera and near lamps, processed raw and corrected, against the same sample "
    "without those effects.",
    "render": "Frames/s of the GL renderer at 800 × 600 against the number of components "
    "and blended view slots, as a ratio to a plain textured quad drawn in the same run, "
    "and the MDF's depth-peeling passes against the BTF alone.",
    "render-loop": "The renderer against the simulator: simulated samples measured on "
    "plans from coarse to H1, processed and rendered at directions no plan captured; "
    "prints PSNR against the noise-free truth beside each plan's capture time.",
    "silhouettes": "MDF silhouettes against the ray-cast truth: intersection over union "
    "and the width of the outline's error band in pixels, per sample, mesh and number "
    "of depth-peeling passes, with the MDF and without it.",
    "environment": "What environment lighting's accuracy costs in time: error of the "
    "visibility maps, their PCA of rotations and the partial environment maps against "
    "a brute-force sum, beside the time per frame as a ratio to a point-light frame.",
    "error-budget": "The render loop's PSNR at captured and held-out directions with the "
    "simulator's noise, near lamps, point-sampled pixels and perspective, and registration's "
    "markers and box filter, switched off one at a time and together, each session processed "
    "raw and corrected, at c = 4 and lossless (coarse and medium plans; --quick: the coarse "
    "plan at 32² texels).",
}

app = typer.Typer(
    no_args_is_help=True,
    help="Benchmarks: accuracy against time, per area.",
    rich_markup_mode=PLAIN_HELP,
)


def print_rows(title: str, rows: list[dict]) -> None:
    """One table, or one per kind when every row names its kind (``"row"`` or ``"kind"``)."""
    key = next((k for k in ("row", "kind") if rows and all(k in r for r in rows)), None)
    if key is not None:
        kinds = dict.fromkeys(r[key] for r in rows)
        if len(kinds) > 1:
            for kind in kinds:
                group = [dict(r) for r in rows if r[key] == kind]
                for r in group:
                    del r[key]
                _print_table(f"{title}: {kind}", group)
            return
    _print_table(title, rows)


def markdown_table(rows: list[dict]) -> str:
    """The rows as one Markdown table (floats to 4 significant digits), for the docs."""
    columns = list(dict.fromkeys(k for row in rows for k in row))
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for row in rows:
        cells = [_cell(row.get(col, "")) for col in columns]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _cell(value) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _print_table(title: str, rows: list[dict]) -> None:
    table = Table(title=title)
    columns = list(dict.fromkeys(k for row in rows for k in row))
    for col in columns:
        table.add_column(col)
    for row in rows:
        table.add_row(*(_cell(row.get(col, "")) for col in columns))
    console.print(table)


def _make(area: str):
    module_name, call = AREAS[area]

    def command(
        json_out: Annotated[
            Path | None, typer.Option("--json", help="also write the rows as JSON")
        ] = None,
        quick: Annotated[bool, typer.Option("--quick", help="smaller sizes, fewer runs")] = False,
        markdown: Annotated[
            Path | None, typer.Option("--markdown", help="also write the rows as a Markdown table")
        ] = None,
    ) -> None:
        with working(f"rig bench {area}: measuring" + (" (--quick)" if quick else "")):
            rows = call(importlib.import_module(module_name), quick)
        print_rows(f"rig bench {area}", rows)
        if json_out is not None:
            json_out.write_text(json.dumps(rows, indent=2, default=float))
        if markdown is not None:
            markdown.write_text(markdown_table(rows))

    command.__doc__ = HELP[area]
    return command


for _area in AREAS:
    app.command(_area)(_make(_area))
