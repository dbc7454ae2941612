"""The ``manifest.json`` every export writes next to its files, and how an export is known.

Every manifest this project writes starts with its own marker,
``"exported_by": "btfrig"``, and every ``.glb`` names btfrig as its glTF
``asset.generator``: ``--overwrite`` replaces only what carries it, never a
folder that merely holds some other ``manifest.json``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

__all__ = ["EXPORTED_BY", "MANIFEST", "is_marked_manifest", "write_manifest"]

#: the manifest's file name (the importer reads a UBO2003 folder's, too)
MANIFEST = "manifest.json"
#: the marker's value: the manifest's first key, and a .glb's asset generator
EXPORTED_BY = "btfrig"
_MARKER = b'{\n "exported_by": "btfrig",'


def write_manifest(out: Path, manifest: dict[str, Any]) -> Path:
    """Write ``manifest`` (plain JSON values, finite) as ``out/manifest.json``, marked; its path."""
    path = Path(out) / MANIFEST
    document = {"exported_by": EXPORTED_BY}
    document.update((k, v) for k, v in manifest.items() if k != "exported_by")
    path.write_text(json.dumps(document, indent=1, allow_nan=False) + "\n")
    return path


def is_marked_manifest(folder: Path) -> bool:
    """Whether ``folder`` holds a manifest this project wrote (links are not followed)."""
    return _starts_with(Path(folder) / MANIFEST, _MARKER)


def _starts_with(path: Path, prefix: bytes) -> bool:
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return False
    try:
        return os.read(fd, len(prefix)) == prefix
    except OSError:
        return False  # a folder, say
    finally:
        os.close(fd)
