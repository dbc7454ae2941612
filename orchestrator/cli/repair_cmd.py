"""`rig repair`: rebuild a damaged archive's journal from what survives."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from orchestrator.cli.common import console

__all__ = ["register"]


def repair(archive: Annotated[Path, typer.Argument(help="session archive")]) -> None:
    """Rebuild an archive's journal where it lost or garbled records.

    Keeps every whole journal record and rebuilds lost steps from the
    records their chunk files carry; what it does not trust (the old
    journal, chunk files of incomplete steps, a folder or link under a chunk's
    name) is moved to the archive's quarantine/ folder, never deleted. An
    archive that opens cleanly is left alone.
    """
    from rig.archive import repair_archive

    report = repair_archive(archive)
    if not report.changed:
        console.print(
            f"{escape(str(archive))}: opens cleanly with {report.committed_steps} "
            "committed steps; nothing to repair"
        )
        return
    if not report.journal_rebuilt:
        console.print(
            f"{escape(str(archive))}: {report.committed_steps} committed steps; set aside "
            f"in {escape(str(report.quarantine))} what is not a chunk file under a chunk's "
            f"name: {escape(', '.join(report.set_aside))}"
        )
        return
    console.print(
        f"{escape(str(archive))}: journal rebuilt: {report.committed_steps} committed "
        f"steps, {report.kept_records} records kept, {len(report.rebuilt_steps)} steps "
        "rebuilt from chunk records"
        + (f" ({_ranges(report.rebuilt_steps)})" if report.rebuilt_steps else "")
    )
    if report.quarantine is not None:
        console.print(f"set aside in {escape(report.quarantine)}: {len(report.set_aside)} item(s)")
    for problem in report.lost:
        console.print(f"  not rebuilt: {escape(problem)}")


def _ranges(indices) -> str:
    """``0–4, 7, 9–10`` for the step indices ``indices``."""
    parts: list[str] = []
    ordered = sorted(indices)
    start = previous = ordered[0]
    for index in [*ordered[1:], None]:
        if index is not None and index == previous + 1:
            previous = index
            continue
        parts.append(str(start) if start == previous else f"{start}–{previous}")
        if index is not None:
            start = previous = index
    return ", ".join(parts)


def register(app: typer.Typer) -> None:
    """Add `rig repair` to ``app``."""
    app.command()(repair)
