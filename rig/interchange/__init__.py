"""Other tools' formats in and out: public BTF data sets into archives, an
archive's frames, normtextures and maps out (``docs/interchange.md``).

Pure I/O over the rig's model: the importer writes through ``rig.archive``,
the map writers read ``rig.material``; what needs processing (registering
frames, reconstructing a compressed BTF) is the caller's.
"""

from rig.interchange._directions import ENCODINGS, FolderFrame, FolderListing, list_folder
from rig.interchange._errors import InterchangeError, InterchangeWriteError
from rig.interchange._frames import FRAME_FORMATS, export_frames
from rig.interchange._gltf import glb_generator, is_export, write_glb
from rig.interchange._gltf_pbr import EXTENSIONS as GLTF_EXTENSIONS
from rig.interchange._gltf_pbr import write_pbr_glb
from rig.interchange._images import (
    IMAGE_SUFFIXES,
    read_image,
    srgb_decode,
    srgb_encode,
    to_srgb,
    write_exr,
    write_image,
)
from rig.interchange._imagesize import MAX_IMAGE_PIXELS, check_image_size, image_size
from rig.interchange._import import (
    NORMTEXTURE_CAMERA,
    ImportReport,
    import_folder,
    imported_normtextures,
)
from rig.interchange._manifest import EXPORTED_BY, MANIFEST, write_manifest
from rig.interchange._maps import TextureMaps, decode_normal_map, texture_maps, write_maps
from rig.interchange._materialx import write_materialx
from rig.interchange._pbr_textures import PbrTextures, pbr_textures
from rig.interchange._ubo2003 import (
    UboFrame,
    UboListing,
    list_ubo2003,
    ubo2003_file,
    ubo2003_view_folder,
    write_ubo2003,
)

__all__ = [
    "ENCODINGS",
    "EXPORTED_BY",
    "FRAME_FORMATS",
    "GLTF_EXTENSIONS",
    "IMAGE_SUFFIXES",
    "MANIFEST",
    "MAX_IMAGE_PIXELS",
    "NORMTEXTURE_CAMERA",
    "FolderFrame",
    "FolderListing",
    "ImportReport",
    "InterchangeError",
    "InterchangeWriteError",
    "PbrTextures",
    "TextureMaps",
    "UboFrame",
    "UboListing",
    "check_image_size",
    "decode_normal_map",
    "export_frames",
    "glb_generator",
    "image_size",
    "import_folder",
    "imported_normtextures",
    "is_export",
    "list_folder",
    "list_ubo2003",
    "pbr_textures",
    "read_image",
    "srgb_decode",
    "srgb_encode",
    "texture_maps",
    "to_srgb",
    "ubo2003_file",
    "ubo2003_view_folder",
    "write_exr",
    "write_glb",
    "write_image",
    "write_manifest",
    "write_maps",
    "write_materialx",
    "write_pbr_glb",
    "write_ubo2003",
]
