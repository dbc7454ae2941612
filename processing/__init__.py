"""Pure numeric stages: arrays in, arrays or frozen dataclasses out, no I/O.

- ``processing.photometric``: normals, albedo and height from images under many lamps.
"""

from processing import photometric

__all__ = ["photometric"]
