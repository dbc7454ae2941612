"""The material format: what a session's processing produces, and its one owner.

Every group of a material carries ``format``/``version`` attributes and has one
writer and one reader here: ``btf`` (compressed BTF), ``ps`` (photometric-stereo
maps per view), ``mdf`` (mesostructure distance function), ``pbr`` (the BTF fitted by a glTF PBR
material), ``live`` (the
workers' per-frame results) and the lamps' flat fields. A material lives in a
session archive's ``material/`` group or in a standalone store
(:func:`export_material`); :func:`read_material` reads either.
``docs/material.md`` describes every group.
"""

from rig.material._btf import BtfGroup, btf_from_arrays, btf_to_arrays, read_btf, write_btf
from rig.material._btf_model import CompressedBTF, GlobalSVD, check_directions
from rig.material._errors import MaterialError
from rig.material._export import export_material
from rig.material._flatfield import (
    FlatFieldMaps,
    archive_flat_field_path,
    copy_flat_field,
    read_flat_field,
    write_flat_field,
)
from rig.material._live import LiveAppender, LiveResults, live_rows, read_live
from rig.material._material import Material, read_material
from rig.material._mdf import UNSEEN, Mdf, read_mdf, write_mdf
from rig.material._pbr import PbrFlag, PbrMaps, pbr_layers, read_pbr, write_pbr
from rig.material._pbr_model import (
    SHEEN_ROUGHNESS_MIN,
    PbrParams,
    anisotropy_frame,
    evaluate_terms,
    sheen_albedo,
)
from rig.material._pbr_model import evaluate as evaluate_pbr
from rig.material._ps import PsView, read_ps, write_ps
from rig.material._radiometry import NOT_RECORDED, Radiometry

__all__ = [
    "NOT_RECORDED",
    "SHEEN_ROUGHNESS_MIN",
    "UNSEEN",
    "BtfGroup",
    "CompressedBTF",
    "FlatFieldMaps",
    "GlobalSVD",
    "LiveAppender",
    "LiveResults",
    "Material",
    "MaterialError",
    "Mdf",
    "PbrFlag",
    "PbrMaps",
    "PbrParams",
    "PsView",
    "Radiometry",
    "anisotropy_frame",
    "archive_flat_field_path",
    "btf_from_arrays",
    "btf_to_arrays",
    "check_directions",
    "copy_flat_field",
    "evaluate_pbr",
    "evaluate_terms",
    "export_material",
    "live_rows",
    "pbr_layers",
    "read_btf",
    "read_flat_field",
    "read_live",
    "read_material",
    "read_mdf",
    "read_pbr",
    "read_ps",
    "sheen_albedo",
    "write_btf",
    "write_flat_field",
    "write_mdf",
    "write_pbr",
    "write_ps",
]
