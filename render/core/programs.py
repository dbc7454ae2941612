"""Shader programs: the one builder every program of the renderers goes through.

A stage is a file of ``render/shaders`` whose first line is ``#version``. The
builder puts the program's ``#define``s right after that line and replaces
every ``#include "name"`` line by the text of ``render/shaders/<name>`` (whose
own includes are resolved the same way), so a shader names the shared code it
needs where it needs it (``directions.glsl``, ``mdf.glsl``, ``pbr.glsl`` …)
and the program's constants decide, through ``#if``, what of it is compiled.
An include inside an ``#if`` group is pasted all the same and skipped by the
GLSL preprocessor when the group is off.
"""

from __future__ import annotations

import re
from importlib.resources import files

import moderngl

from render._errors import RenderError

__all__ = ["build_program", "shader_source", "stage_source"]

_INCLUDE = re.compile(r'^[ \t]*#include[ \t]+"([^"]+)"[ \t]*$', re.MULTILINE)
_VERSION = re.compile(r"\A#version [^\n]*\n")


def shader_source(name: str) -> str:
    """The text of ``render/shaders/<name>`` as stored (no defines, includes unresolved)."""
    path = files("render").joinpath("shaders", name)
    if not path.is_file():
        raise RenderError(f"shader {name!r}: no such file in render/shaders")
    return path.read_text()


def _resolved(text: str, within: tuple[str, ...]) -> str:
    """``text`` with every ``#include`` line replaced by the file's resolved text."""

    def paste(match: re.Match) -> str:
        name = match.group(1)
        if name in within:
            raise RenderError(f"shader {within[-1]!r}: includes {name!r} within itself")
        included = shader_source(name)
        if _VERSION.match(included):
            raise RenderError(f"shader {name!r} has a #version line and cannot be included")
        return _resolved(included, (*within, name)).rstrip("\n")

    return _INCLUDE.sub(paste, text)


def stage_source(stage: str, defines: dict[str, int | float] | None = None) -> str:
    """The GLSL the GL compiles for ``stage``: ``#version``, the ``defines``, the rest
    with its includes resolved.

    Parameters
    ----------
    stage : str
        A file of ``render/shaders`` (``"surface.frag"``) or GLSL text of several lines
        (a test's own stage); its first line is ``#version``.
    defines : dict of str to int or float, optional
        ``#define NAME value`` each, in order.
    """
    name = stage if "\n" not in stage else "<text>"
    text = stage if "\n" in stage else shader_source(stage)
    version = _VERSION.match(text)
    if version is None:
        raise RenderError(f"shader {name!r}: its first line must be #version")
    header = version.group(0) + "".join(f"#define {k} {v}\n" for k, v in (defines or {}).items())
    return header + _resolved(text[version.end() :], (name,))


def build_program(
    ctx: moderngl.Context,
    vertex: str,
    fragment: str,
    *,
    defines: dict[str, int | float] | None = None,
) -> moderngl.Program:
    """The program of the ``vertex`` and ``fragment`` stages (:func:`stage_source`),
    both compiled with ``defines``.

    Raises
    ------
    RenderError
        A stage this GL cannot compile, naming it and the driver's message.
    """
    try:
        return ctx.program(
            vertex_shader=stage_source(vertex, defines),
            fragment_shader=stage_source(fragment, defines),
        )
    except moderngl.Error as err:
        names = " + ".join(s if "\n" not in s else "<text>" for s in (vertex, fragment))
        raise RenderError(f"the shader {names} does not compile on this GL: {err}") from err
