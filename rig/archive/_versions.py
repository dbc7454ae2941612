"""Versions of the software that wrote an archive, for provenance."""

from __future__ import annotations

import platform
import sys
from importlib import metadata

__all__ = ["software_versions"]

# Distribution names (not import names) whose versions an archive records.
_DISTRIBUTIONS = (
    "btfrig",
    "numpy",
    "scipy",
    "zarr",
    "numcodecs",
    "opencv-python-headless",
    "pydantic",
    "pyzmq",
    "pymodbus",
    "dynamixel-sdk",
)


def software_versions() -> dict[str, str]:
    """Versions of Python, the platform and the distributions btfrig relies on.

    A distribution that is not installed is reported as ``"not installed"``;
    the lookup reads package metadata only and imports nothing.
    """
    versions = {"python": sys.version.split()[0], "platform": platform.platform()}
    for name in _DISTRIBUTIONS:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return versions
