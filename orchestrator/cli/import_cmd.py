"""`rig import FOLDER --out ARCHIVE`: a public BTF data set into a session archive."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from orchestrator.cli.common import check_new_archive, console, terminating_as_interrupt

__all__ = ["register"]


def import_(
    folder: Annotated[
        Path,
        typer.Argument(
            help="a UBO2003 folder (tv…_pv… views), or a folder of frames with "
            "directions.csv or directions.toml"
        ),
    ],
    out: Annotated[Path, typer.Option("--out", help="archive to create")],
    sample_mm: Annotated[
        float | None,
        typer.Option(
            "--sample-mm",
            min=1e-3,
            help="side of the imaged sample, mm (default: a btfrig export's manifest "
            "says, else 100)",
        ),
    ] = None,
    encoding: Annotated[
        str | None,
        typer.Option(
            help="srgb | linear: how the files' integers encode radiance (default: srgb "
            "for UBO2003 and 8-bit files, linear for 16-bit; OpenEXR is linear)"
        ),
    ] = None,
) -> None:
    """Read a BTF data set's images and directions into an archive.

    The images are rectified (normtextures); they are stored linear (sRGB-encoded
    files decoded), so that `rig process --stages btf` (registration skipped) and
    `rig view` work on it. Views missing lights are imported and listed; an unparseable name, a
    non-image or an image of another size fails naming the file. An
    interrupted import (Ctrl-C or SIGTERM) leaves no archive behind.
    """
    from rig.interchange import import_folder

    check_new_archive(out, "--out", otherwise="remove it first")
    columns = (TextColumn("[bold]import"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn())  # fmt: skip
    with (
        terminating_as_interrupt(),
        Progress(*columns, console=console, transient=True) as bar,
    ):
        task = bar.add_task("import", total=None)
        report = import_folder(
            folder, out, sample_mm=sample_mm, encoding=encoding,
            progress=lambda done, total: bar.update(task, completed=done, total=total),
        )  # fmt: skip
    height, width, channels = report.shape
    console.print(escape(
        f"{report.archive}: {report.frames} frames ({report.layout}), {report.views} views × "
        f"{report.lights} lights, {width}×{height}×{channels}, {report.encoding} → linear, "
        f"sample {report.sample_mm:g} mm"
    ))  # fmt: skip
    for gap in report.gaps:
        console.print(escape(f"gap: {gap}"), style="yellow")


def register(app: typer.Typer) -> None:
    """Add `rig import` to ``app``."""
    app.command("import")(import_)
