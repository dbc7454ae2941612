"""`rig bench NAME`: the studies (``studies.STUDIES``), each a table of rows measured
against a truth or a baseline drawn in the same run; their tables and figures are the docs'."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from orchestrator.cli.common import PLAIN_HELP, console, quiet_dask_logs, working
from studies import STUDIES, Study

__all__ = ["app", "markdown_table"]


app = typer.Typer(
    no_args_is_help=True,
    help="Studies: accuracy against a truth, and what it costs in time.",
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


JsonOption = Annotated[Path | None, typer.Option("--json", help="also write the rows as JSON")]
QuickOption = Annotated[bool, typer.Option("--quick", help="smaller sizes, fewer runs")]
MarkdownOption = Annotated[
    Path | None, typer.Option("--markdown", help="also write the rows as a Markdown table")
]
PlotOption = Annotated[Path | None, typer.Option("--plot", help="also draw the rows (PNG)")]


def _run(study: Study, quick: bool, json_out: Path | None, markdown: Path | None,
         plot: Path | None) -> None:  # fmt: skip
    # Studies that process (through Dask) log as `rig process` does; the rest need no Dask.
    if importlib.util.find_spec("distributed") is not None:
        quiet_dask_logs()
    with working(f"rig bench {study.name}: measuring" + (" (--quick)" if quick else "")):
        module = study.load()
        rows = module.run(quick)
    print_rows(f"rig bench {study.name}", rows)
    if json_out is not None:
        json_out.write_text(json.dumps(rows, indent=2, default=float))
    if markdown is not None:
        markdown.write_text(markdown_table(rows))
    if plot is not None:
        module.plot(rows, plot)


def _make(study: Study):
    """The study's command; ``--plot`` where its rows have a figure."""

    def command(
        json_out: JsonOption = None, quick: QuickOption = False, markdown: MarkdownOption = None
    ) -> None:
        _run(study, quick, json_out, markdown, None)

    def command_with_plot(
        json_out: JsonOption = None,
        quick: QuickOption = False,
        markdown: MarkdownOption = None,
        plot: PlotOption = None,
    ) -> None:
        _run(study, quick, json_out, markdown, plot)

    chosen = command_with_plot if study.figure else command
    chosen.__doc__ = study.description
    return chosen


for _study in STUDIES:
    app.command(_study.name, short_help=_study.summary)(_make(_study))
