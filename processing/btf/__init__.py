"""BTF compression and interpolation: per-view PCA and the global SVD.

Seed ``000_…`` §4.1–4.2 (per-view-slot PCA, 4-nearest light interpolation,
view-slot blending) and seed ``001_…`` §5 (one SVD with views as columns).
The models :class:`CompressedBTF` and :class:`GlobalSVD` are the material format's
(``rig.material``, ``docs/material.md``), re-exported here; normtextures
stored in sRGB are decoded with :func:`to_linear` (and encoded back with
:func:`from_linear`); a single view slot reconstructs and interpolates on
its own (:meth:`ViewSlot.reconstruct`, :meth:`ViewSlot.interpolate`);
``rig bench btf`` runs :func:`studies.btf_compression.run`.
"""

from processing.btf._colour import (
    COLOUR_SPACES,
    ColourSpace,
    from_linear,
    linear_units,
    to_linear,
)
from processing.btf._compress import compress_btf, compress_global_svd
from processing.btf._errors import BtfError
from processing.btf._interpolate import (
    Method,
    direction_weights,
    interpolate,
    light_weights,
    reconstruct,
)
from processing.btf._pca import ViewSlot, compress_view, compress_view_svd
from processing.btf._quality import psnr_db, rmse
from processing.btf._slots import Displaced, SlotTable, view_slots
from rig.material import CompressedBTF, GlobalSVD

__all__ = [
    "COLOUR_SPACES",
    "BtfError",
    "ColourSpace",
    "CompressedBTF",
    "Displaced",
    "GlobalSVD",
    "Method",
    "SlotTable",
    "ViewSlot",
    "compress_btf",
    "compress_global_svd",
    "compress_view",
    "compress_view_svd",
    "direction_weights",
    "from_linear",
    "interpolate",
    "light_weights",
    "linear_units",
    "psnr_db",
    "reconstruct",
    "rmse",
    "to_linear",
    "view_slots",
]
