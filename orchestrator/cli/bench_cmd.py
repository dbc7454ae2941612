"""`rig bench NAME`: the studies (``studies.STUDIES``), each a table of rows measured
against a truth or a baseline drawn in the same run; their tables and figures are the docs'."""

from __future__ import annotations

import importlib.util
import inspect
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


#: The options a study may offer beside ``--quick`` (``Study.selects``): the keyword of
#: its ``run``, the option and its metavar, its type, its help, and the module's table
#: of valid values (for ``render_scale``, its largest value).
SELECTIONS: dict[str, tuple[str, type, str, str | None]] = {
    "scenes": ("--sample <sample>", list[str] | None,
               "a simulated sample: bumps or weave (repeat for several; default: both)", "SCENES"),
    "plans": ("--plan <plan>", list[str] | None,
              "a plan: coarse, medium, fine or H1 (repeat for several; default: the study's)",
              "PLANS"),
    "render_scale": ("--render-scale <scale>", float | None,
                     "the frames' resolution as a fraction of the camera's, 0 < s ≤ 4 (1: its own;"
                     " default: the loop's 0.5)", "MAX_RENDER_SCALE"),
    "processings": ("--processing <processing>", list[str] | None,
                    "how each session is processed: raw, irradiance-per-texel, lights-per-texel, "
                    "lights-and-views-per-texel, lights-by-model, lights-and-views-by-model "
                    "(repeat for several; default: raw and irradiance-per-texel)", "PROCESSINGS"),
    "runs": ("--run <terms>", list[str] | None,
             "one run: the error terms it switches off, comma-separated (noise, near-lamps, "
             "point-pixels, perspective, marker-registration, box-filter), 'none' for all on, "
             "'all' for all off (repeat for several; default: all on, each alone, all off)",
             "TERMS"),
}  # fmt: skip


def _selected(module, name: str, values):
    """The ``run`` argument of one selection, checked against the module's valid values
    (a hyphen reads as a space): a bad one is the user's input, exit 2."""
    option = SELECTIONS[name][0].split()[0]
    table = SELECTIONS[name][3]
    if name == "render_scale":
        most = getattr(module, table)
        if not 0 < values <= most:
            raise typer.BadParameter(f"{values:g}: valid is 0 < scale ≤ {most:g}",
                                     param_hint=option)  # fmt: skip
        return float(values)
    valid = list(getattr(module, table))

    def known(value: str) -> str:
        spaced = value.strip().replace("-", " ")
        match = next((v for v in valid if v.lower() == spaced.lower()), None)
        if match is None:
            shown = ", ".join(v.replace(" ", "-") for v in valid)
            raise typer.BadParameter(f"{value!r}: valid are {shown}", param_hint=option)
        return match

    if name != "runs":
        return tuple(known(v) for v in values)
    runs = []
    for run in values:
        spaced = run.strip().lower()
        runs.append(() if spaced == "none" else tuple(valid) if spaced == "all"
                    else tuple(known(term) for term in run.split(",")))  # fmt: skip
    return tuple(runs)


def _run(study: Study, quick: bool, json_out: Path | None, markdown: Path | None,
         plot: Path | None, selected: dict) -> None:  # fmt: skip
    # Studies that process (through Dask) log as `rig process` does; the rest need no Dask.
    if importlib.util.find_spec("distributed") is not None:
        quiet_dask_logs()
    module = study.load()
    chosen = {name: _selected(module, name, value)
              for name, value in selected.items() if value not in (None, [])}  # fmt: skip
    with working(f"rig bench {study.name}: measuring" + (" (--quick)" if quick else "")):
        rows = module.run(quick, **chosen)
    print_rows(f"rig bench {study.name}", rows)
    if json_out is not None:
        json_out.write_text(json.dumps(rows, indent=2, default=float))
    if markdown is not None:
        markdown.write_text(markdown_table(rows))
    if plot is not None:
        module.plot(rows, plot)


def _make(study: Study):
    """The study's command: ``--json``, ``--quick``, ``--markdown``, ``--plot`` where its
    rows have a figure, and the options of its :data:`SELECTIONS`."""

    def command(**options) -> None:
        selected = {name: options.pop(name) for name in study.selects}
        _run(study, options["quick"], options["json_out"], options["markdown"],
             options.get("plot"), selected)  # fmt: skip

    keyword = inspect.Parameter.KEYWORD_ONLY
    params = [
        inspect.Parameter("json_out", keyword, default=None, annotation=JsonOption),
        inspect.Parameter("quick", keyword, default=False, annotation=QuickOption),
        inspect.Parameter("markdown", keyword, default=None, annotation=MarkdownOption),
    ]
    if study.figure:
        params.append(inspect.Parameter("plot", keyword, default=None, annotation=PlotOption))
    for name in study.selects:
        option, kind, text, _ = SELECTIONS[name]
        flag, metavar = option.split()
        params.append(inspect.Parameter(name, keyword, default=None, annotation=Annotated[
            kind, typer.Option(flag, help=text, metavar=metavar)
        ]))  # fmt: skip
    command.__signature__ = inspect.Signature(params)
    command.__doc__ = study.description
    return command


for _study in STUDIES:
    app.command(_study.name, short_help=_study.summary)(_make(_study))
