"""`rig export FORMAT ARCHIVE --out PATH`: a session's results in other formats.

``material`` writes the standalone material store (``rig.material.export_material``)
that ``rig view`` and other labs read without the session's frames.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from orchestrator.cli.common import console, not_built
from rig.errors import ConfigError

__all__ = ["app"]

app = typer.Typer(
    help="Write a session's material or frames in other formats.", no_args_is_help=True
)

#: formats named in the design whose writers are not built yet
_PENDING = {
    "png16": "16-bit PNG frames",
    "tiff": "TIFF frames",
    "exr": "OpenEXR frames",
    "ubo2003": "the Bonn UBO2003 folder layout",
}

_Archive = Annotated[Path, typer.Argument(help="session archive", show_default=False)]


@app.command()
def material(
    archive: _Archive,
    out: Annotated[Path, typer.Option("--out", help="material store to create (M.zarr)")],
) -> None:
    """The material (btf, ps, mdf, sample size, calibration provenance), no frames."""
    from rig.material import export_material

    if not (archive / "zarr.json").is_file() or not (archive / "material").is_dir():
        raise ConfigError(f"{archive}: not a session archive (no zarr.json and material/ there)")
    if out.exists():
        raise ConfigError(f"{out}: already exists; give --out a new path")
    written = export_material(archive, out)
    console.print(f"material store: {written}")


def _pending(fmt: str, what: str) -> None:
    def command(
        archive: _Archive,
        out: Annotated[Path, typer.Option("--out", help="output folder")],
    ) -> None:
        not_built(f"export {fmt}", f"the exporter to {what}")

    command.__doc__ = f"{what[0].upper()}{what[1:]} (not built yet)."
    app.command(fmt)(command)


for _fmt, _what in _PENDING.items():
    _pending(_fmt, _what)
