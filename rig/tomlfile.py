"""TOML files a person writes: reading them, and saying which field is wrong.

``read_toml`` (and its parts ``file_text`` and ``toml_data``) turn every reason a
file cannot be read into one sentence naming the file; ``format_validation_error``
turns a pydantic ``ValidationError`` into one line per problem: the field's
dotted path (without the tags pydantic adds for tagged unions), the value, and
what would be valid there. Rig configs, plans, scenes and calibration files are
read through them; ``write_toml`` writes one so that a reader sees the whole file
or none (a daemon started as soon as a simulated rig's config appears).
"""

from __future__ import annotations

import os
import reprlib
import tomllib
from pathlib import Path

import tomli_w
from pydantic import BaseModel, ValidationError

from rig.errors import ConfigError

__all__ = ["file_text", "format_validation_error", "read_toml", "toml_data", "write_toml"]


def _locate(model: type[BaseModel] | None, loc: tuple) -> tuple[tuple, type[BaseModel] | None]:
    """``loc`` without the tags pydantic adds for tagged unions, and the model that
    holds its last part (None where the walk cannot tell)."""
    shown: list = []
    parts = list(loc)
    while parts:
        part = parts.pop(0)
        shown.append(part)
        if not parts:
            break
        if model is None or not isinstance(part, str) or part not in model.model_fields:
            model = None
            continue
        members = _models_in(model.model_fields[part].annotation)
        if parts and isinstance(parts[0], int):  # an item of a list of models
            shown.append(parts.pop(0))
        kinds = {_kind_of(m): m for m in members}
        if parts and len(parts) > 1 and parts[0] in kinds:  # a tagged union's tag
            model = kinds[parts.pop(0)]
        else:
            model = members[0] if len(members) == 1 else None
    return tuple(shown), model


def _models_in(annotation) -> list[type[BaseModel]]:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    found: list[type[BaseModel]] = []
    for arg in getattr(annotation, "__args__", ()) + getattr(annotation, "__metadata__", ()):
        found += [m for m in _models_in(arg) if m not in found]
    origin = getattr(annotation, "__origin__", None)
    return found or (_models_in(origin) if origin is not None else [])


def _kind_of(model: type[BaseModel]) -> str | None:
    field = model.model_fields.get("kind")
    return field.default if field is not None else None


# A value shown in an error: a few levels and items, so a huge or deeply nested
# input gives a short line.
_SHORT = reprlib.Repr()
_SHORT.maxlevel, _SHORT.maxlist, _SHORT.maxtuple, _SHORT.maxstring = 3, 6, 6, 80


def format_validation_error(
    source: str, err: ValidationError, model: type[BaseModel] | None = None
) -> list[str]:
    """One line per problem: the field's dotted path, the value, what is valid.

    With ``model`` (the root model validated), an unknown field's line lists
    the valid field names at that place.
    """
    lines = []
    for e in err.errors():
        loc, holder = _locate(model, e["loc"])
        where = ".".join(str(p) for p in loc) or "(top level)"
        value = e.get("input")
        if e["type"] == "extra_forbidden":
            hint = f"; valid fields here are {sorted(holder.model_fields)}" if holder else ""
            lines.append(f"{where}: unknown field{hint}")
            continue
        if e["type"] in ("union_tag_invalid", "union_tag_not_found"):
            tag = e.get("ctx", {}).get("tag")
            got = f"kind {tag!r} is not known here" if tag is not None else "kind is missing"
            valid = e.get("ctx", {}).get("expected_tags")
            if valid is None and holder is not None and loc[-1] in holder.model_fields:
                members = _models_in(holder.model_fields[loc[-1]].annotation)
                valid = ", ".join(repr(_kind_of(m)) for m in members)
            lines.append(f"{where}: {got}" + (f"; valid kinds are {valid}" if valid else ""))
            continue
        msg = e["msg"].removeprefix("Value error, ")
        shown = "" if isinstance(value, dict) else f" (got {_SHORT.repr(value)})"
        lines.append(f"{where}: {msg}{shown}")
    return lines


def file_text(path: Path) -> str:
    """The UTF-8 text of file ``path``; a ``ValueError`` saying why it cannot be
    read ("does not exist", "is a folder, not a TOML file", …)."""
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError("does not exist") from None
    except IsADirectoryError:
        raise ValueError("is a folder, not a TOML file") from None
    except UnicodeDecodeError as err:
        raise ValueError(
            f"is not UTF-8 text (byte {err.start} is {err.object[err.start]:#04x}); "
            "give a TOML text file"
        ) from None
    except OSError as err:
        raise ValueError(f"cannot be read: {err.strerror}") from None


def toml_data(text: str) -> dict:
    """The data of TOML ``text``; a ``ValueError`` saying why it is not TOML."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"is not valid TOML: {err}") from None
    except RecursionError:
        # tomllib parses nested arrays and inline tables recursively
        raise ValueError("nests arrays or inline tables too deeply to be read") from None


def read_toml(path: str | Path, what: str) -> dict:
    """The data of TOML file ``path``; a ``ConfigError`` naming ``what``, the
    file and why when it cannot be read or is not TOML."""
    try:
        return toml_data(file_text(Path(path)))
    except ValueError as err:
        raise ConfigError(f"{what} {path} {err}") from None


def write_toml(data: dict, path: str | Path) -> Path:
    """Write ``data`` as TOML at ``path`` (its folder made), atomically: a temporary
    sibling renamed over it, so a reader or a crash sees the old file or the new one."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(tomli_w.dumps(data))
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
