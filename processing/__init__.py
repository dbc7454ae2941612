"""Pure numeric stages: arrays in, arrays or frozen dataclasses out, no I/O.

- ``processing.photometric``: normals, albedo and height from images under many lamps.
- ``processing.mdf``: the mesostructure distance function from laser scans.
"""

from processing import mdf, photometric

__all__ = ["mdf", "photometric"]
