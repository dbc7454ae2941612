"""`rig bench AREA`: what accuracy costs in time, measured against baselines
in the same run. Each area's benchmark lives with its code and returns rows."""

from __future__ import annotations

import importlib
import json
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from rig.cli.common import console, not_built, reporting_errors

__all__ = ["app"]

# area → (module, issue that builds it)
AREAS = {
    "archive": ("rig.archive.bench", 2),
    "sim": ("sim.bench", 3),
    "ps": ("processing.photometric.bench", 6),
    "btf": ("processing.btf.bench", 7),
    "mdf": ("processing.mdf.bench", 8),
    "calibration": ("calibration.bench", 9),
}

app = typer.Typer(no_args_is_help=True, help="Benchmarks: accuracy against time, per area.")


def print_rows(title: str, rows: list[dict]) -> None:
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
    def command(
        json_out: Annotated[
            Path | None, typer.Option("--json", help="also write the rows as JSON")
        ] = None,
        quick: Annotated[bool, typer.Option("--quick", help="smaller sizes, fewer runs")] = False,
    ) -> None:
        module_name, issue = AREAS[area]
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as err:
            if err.name is not None and module_name.startswith(err.name):
                not_built(f"bench {area}", issue, f"the {area} benchmark")
            raise
        with reporting_errors():
            rows = module.run_bench(quick=quick)
        print_rows(f"rig bench {area}", rows)
        if json_out is not None:
            json_out.write_text(json.dumps(rows, indent=2, default=float))

    command.__doc__ = f"Benchmark the {area} stage (issue {AREAS[area][1]})."
    return command


for _area in AREAS:
    app.command(_area)(_make(_area))
