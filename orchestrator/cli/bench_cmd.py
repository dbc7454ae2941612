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

from orchestrator.cli.common import console
from rig.config import default_rig_config
from rig.plan import parse_plan
from rig.schedule import compile_plan

__all__ = ["app"]


def _archive(module, quick: bool) -> list[dict]:
    with tempfile.TemporaryDirectory(prefix="rig-bench-") as tmp:
        return module.run_bench(tmp, n_steps=8 if quick else 32, repeats=1 if quick else 3)


def _plain(module, quick: bool) -> list[dict]:
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
    "sim": ("sim.bench", _plain),
    "ps": ("processing.photometric.bench", _ps),
    "btf": ("processing.btf.bench", _btf),
    "mdf": ("processing.mdf.bench", _plain),
    "calibration": ("orchestrator.calibration_bench", _plain),
    "render": ("render.bench", _plain),
    "render-loop": ("orchestrator.render_loop", _plain),
    "silhouettes": ("orchestrator.silhouettes", _plain),
    "environment": ("render.env_bench", _plain),
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


def _print_table(title: str, rows: list[dict]) -> None:
    table = Table(title=title)
    columns = list(dict.fromkeys(k for row in rows for k in row))
    for col in columns:
        table.add_column(col)
    for row in rows:
        cells = []
        for col in columns:
            value = row.get(col, "")
            cells.append(f"{value:.4g}" if isinstance(value, float) else str(value))
        table.add_row(*cells)
    console.print(table)


def _make(area: str):
    module_name, call = AREAS[area]

    def command(
        json_out: Annotated[
            Path | None, typer.Option("--json", help="also write the rows as JSON")
        ] = None,
        quick: Annotated[bool, typer.Option("--quick", help="smaller sizes, fewer runs")] = False,
    ) -> None:
        rows = call(importlib.import_module(module_name), quick)
        print_rows(f"rig bench {area}", rows)
        if json_out is not None:
            json_out.write_text(json.dumps(rows, indent=2, default=float))

    command.__doc__ = f"Run the {area} benchmark (against baselines measured in the same run)."
    return command


for _area in AREAS:
    app.command(_area)(_make(_area))
