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

from orchestrator.cli.common import console, quiet_dask_logs
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
    "daemon": ("orchestrator.daemon.bench", _plain),
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

# an area's help where the generic line says too little
HELP = {
    "process": "Items/s of `rig process --stages ps` on a simulated session against Dask "
    "workers (1, 2, all cores; threads and worker processes) and --size; speed-up against "
    "one worker in the same run.",
    "error-budget": "The render loop's PSNR at captured and held-out directions with the "
    "simulator's noise, near lamps and point-sampled pixels switched off one at a time and "
    "together, each session processed raw and corrected, at c = 4 and lossless (coarse and "
    "medium plans; --quick: the coarse plan at 32² texels).",
}

app = typer.Typer(no_args_is_help=True, help="Benchmarks: accuracy against time, per area.")


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
        rows = call(importlib.import_module(module_name), quick)
        print_rows(f"rig bench {area}", rows)
        if json_out is not None:
            json_out.write_text(json.dumps(rows, indent=2, default=float))
        if markdown is not None:
            markdown.write_text(markdown_table(rows))

    command.__doc__ = HELP.get(
        area, f"Run the {area} benchmark (against baselines measured in the same run)."
    )
    return command


for _area in AREAS:
    app.command(_area)(_make(_area))
