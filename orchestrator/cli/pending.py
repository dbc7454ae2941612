"""Commands DESIGN.md names whose implementation has not landed yet.

Each exists with its help text and fails with exit code 3, saying so: no fake
success. A command moves out of this module when it is built.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from orchestrator.cli.common import not_built

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    @app.command("import")
    def import_(
        folder: Annotated[Path, typer.Argument(help="a Bonn UBO2003 folder")],
        out: Annotated[Path, typer.Option("--out", help="archive to create")],
    ) -> None:
        """Read a BTF in the Bonn UBO2003 layout into an archive."""
        not_built("import", "the UBO2003 importer")
