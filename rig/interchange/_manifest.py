"""The ``manifest.json`` every export writes next to its files."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

__all__ = ["MANIFEST", "write_manifest"]

#: the manifest's file name (the importer reads a UBO2003 folder's, too)
MANIFEST = "manifest.json"


def write_manifest(out: Path, manifest: dict[str, Any]) -> Path:
    """Write ``manifest`` (plain JSON values, finite) as ``out/manifest.json``; its path."""
    path = Path(out) / MANIFEST
    path.write_text(json.dumps(manifest, indent=1, allow_nan=False) + "\n")
    return path
