"""Pure numeric stages: arrays in, arrays or frozen dataclasses out, no I/O.

- ``processing.photometric``: normals, albedo and height from images under many lamps.
- ``processing.registration``: holder markers → homography → rectified normtextures.
- ``processing.btf``: per-view PCA and global SVD compression, light/view interpolation.
- ``processing.mdf``: the mesostructure distance function from laser scans.
"""

from processing import btf, mdf, photometric, registration

__all__ = ["btf", "mdf", "photometric", "registration"]
