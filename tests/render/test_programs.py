"""The one program builder (defines, includes) and texture units handed out by name."""

import moderngl
import numpy as np
import pytest

from render import RenderError
from render.core.gl import gl_context
from render.core.programs import build_program, shader_source, stage_source
from render.core.units import TextureUnits

_QUAD_VERT = """#version 330
in vec2 in_xy;
void main() { gl_Position = vec4(in_xy, 0.0, 1.0); }
"""
_TWO_SAMPLERS = """#version 330
uniform sampler2D first;
uniform sampler2D second;
out vec4 frag;
void main() { frag = texture(first, vec2(0.5)) + 2.0 * texture(second, vec2(0.5)); }
"""


def test_defines_follow_the_version_line_and_includes_are_pasted_in_place():
    stage = '#version 330\n// before\n#include "mdf.glsl"\n// after\n'
    text = stage_source(stage, {"MDF_VIEW_METHOD": 0, "MDF_VIEW_K": 4})
    lines = text.splitlines()
    assert lines[:3] == ["#version 330", "#define MDF_VIEW_METHOD 0", "#define MDF_VIEW_K 4"]
    assert "#include" not in text
    mdf = shader_source("mdf.glsl").rstrip("\n")
    assert text.index("// before") < text.index(mdf) < text.index("// after")


def test_the_surface_stage_names_the_shared_code_it_compiles():
    text = stage_source("surface.frag", {"PBR": 0, "MDF": 0})
    for name in ("directions.glsl", "pbr.glsl", "mdf.glsl", "mdf_shadow.glsl"):
        assert shader_source(name).rstrip("\n") in text
    assert [line for line in text.splitlines() if line.startswith("#version")] == ["#version 330"]


@pytest.mark.parametrize(
    ("stage", "named"),
    [
        ('#version 330\n#include "nowhere.glsl"\n', "nowhere.glsl"),
        ('#version 330\n#include "depth.frag"\n', "depth.frag"),  # a stage, not a part
        ("// no version\nvoid main() {}\n", "<text>"),
        ("missing.frag", "missing.frag"),
    ],
)
def test_a_bad_stage_or_include_is_named(stage, named):
    with pytest.raises(RenderError, match=named):
        stage_source(stage)


def test_a_stage_that_does_not_compile_is_named_with_the_drivers_message():
    broken = "#version 330\nout vec4 frag;\nvoid main() { frag = undeclared; }\n"
    with pytest.raises(RenderError, match=r"(?s)<text>.*does not compile.*undeclared"):
        build_program(gl_context(), _QUAD_VERT, broken)


def test_units_are_one_per_name_and_samplers_read_their_own_texture():
    ctx = gl_context()
    program = build_program(ctx, _QUAD_VERT, _TWO_SAMPLERS)
    units = TextureUnits(ctx)
    textures = [ctx.texture((1, 1), 1, np.float32([value]), dtype="f4") for value in (1.0, 10.0)]
    quad = ctx.buffer(np.float32([-1, -1, 1, -1, -1, 1, 1, 1]))
    vao = ctx.vertex_array(program, [(quad, "2f", "in_xy")])
    colour = ctx.renderbuffer((1, 1), 4, dtype="f4")
    fbo = ctx.framebuffer([colour])
    try:
        units.unit("shadow_maps")  # a name another program of the renderer asked for first
        units.hold("second", textures[1])
        units.point(program)
        units.use("first", textures[0], program)
        units.bind_held()
        assert len({units.unit(n) for n in ("shadow_maps", "first", "second")}) == 3
        assert units.unit("second") == units.unit("second")
        assert program["first"].value == units.unit("first")
        fbo.use()
        fbo.clear()
        vao.render(moderngl.TRIANGLE_STRIP)
        assert np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32)[0] == 21.0
    finally:
        for obj in (fbo, colour, vao, quad, *textures, program):
            obj.release()


def test_more_names_than_the_gl_has_units_is_refused_naming_the_sampler():
    ctx = gl_context()
    units = TextureUnits(ctx)
    limit = int(ctx.info["GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS"])
    for i in range(limit):
        units.unit(f"sampler_{i}")
    with pytest.raises(RenderError, match="'one_too_many'"):
        units.unit("one_too_many")
