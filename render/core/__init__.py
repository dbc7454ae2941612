"""What every renderer family shares on the GPU.

- :mod:`render.core.gl`: the process's one headless context, framebuffers, mesh buffers;
- :mod:`render.core.programs`: the one program builder (stage files, ``#define``s, ``#include``s);
- :mod:`render.core.units`: texture units handed out by sampler name;
- :mod:`render.core.textures`: material arrays as textures (BTF, PS maps, PBR maps);
- :mod:`render.core.lookup`: direction lookups that blend measured directions as
  ``rig.geometry`` does;
- :mod:`render.core.hemisphere`: the hemicube quadrature and its light table.
"""

from render.core.gl import gl_context, image_framebuffer, mesh_buffers, vertex_array
from render.core.programs import build_program, shader_source, stage_source
from render.core.units import TextureUnits

__all__ = [
    "TextureUnits",
    "build_program",
    "gl_context",
    "image_framebuffer",
    "mesh_buffers",
    "shader_source",
    "stage_source",
    "vertex_array",
]
