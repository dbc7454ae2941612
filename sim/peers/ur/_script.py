"""The URScript the simulated controller understands: a program of motion statements.

A program is either one statement or a ``def name():`` … ``end`` block of
them. Statements: ``set_tcp(p[…])``, ``movej(q, a=…, v=…)`` with ``q`` a joint
list ``[…]`` (rad) or a pose ``p[…]``, ``movel(p[…], a=…, v=…)`` and
``stopj(a)``; ``a`` and ``v`` are optional keywords (the controller's defaults
apply). Anything else is a compile error, as on a controller, and the program
does not run.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["Program", "ScriptError", "Statement", "parse_program"]

_STATEMENT = re.compile(r"^(?P<name>[a-z_]+)\((?P<args>.*)\)$")
_VECTOR = re.compile(r"^(?P<pose>p?)\[(?P<values>[^\[\]]*)\]$")
_DEFAULTS = {"movej": {"a": 1.4, "v": 1.05}, "movel": {"a": 1.2, "v": 0.25}}  # the manual's


class ScriptError(ValueError):
    """A program the controller would not compile or run."""


@dataclass(frozen=True)
class Statement:
    """One call: ``name``, its vector argument (``is_pose``: a ``p[…]``), its keywords."""

    name: str
    vector: tuple[float, ...] = ()
    is_pose: bool = False
    keywords: tuple[tuple[str, float], ...] = ()

    def keyword(self, key: str) -> float:
        return dict(self.keywords)[key]


@dataclass(frozen=True)
class Program:
    name: str
    statements: tuple[Statement, ...]


def parse_program(text: str) -> Program:
    """Parse a program sent to the controller; ``ScriptError`` says what is wrong."""
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    if not lines:
        raise ScriptError("an empty program")
    name = "<unnamed>"
    header = re.match(r"^def ([A-Za-z_][A-Za-z0-9_]*)\(\):$", lines[0])
    if header:
        if lines[-1] != "end":
            raise ScriptError(f"def {header.group(1)}() has no 'end'")
        name, lines = header.group(1), lines[1:-1]
    return Program(name, tuple(_statement(line) for line in lines))


def _statement(line: str) -> Statement:
    match = _STATEMENT.match(line)
    if not match:
        raise ScriptError(f"syntax error in {line!r}")
    name, args = match.group("name"), _split(match.group("args"))
    if name == "stopj":
        if len(args) != 1:
            raise ScriptError(f"stopj takes one deceleration; got {line!r}")
        return Statement(name, keywords=(("a", _number(args[0], line)),))
    if name not in ("movej", "movel", "set_tcp"):
        raise ScriptError(f"unknown function {name!r} in {line!r}")
    if not args:
        raise ScriptError(f"{name} needs a target in {line!r}")
    vector = _VECTOR.match(args[0])
    if not vector:
        raise ScriptError(f"{name}: the first argument of {line!r} is not a list or pose")
    values = tuple(_number(v, line) for v in vector.group("values").split(","))
    is_pose = vector.group("pose") == "p"
    if len(values) != 6 or (name != "movej" and not is_pose):
        raise ScriptError(f"{name} needs {'p[…]' if name != 'movej' else 'six values'}: {line!r}")
    keywords = dict(_DEFAULTS.get(name, {}))
    for arg in args[1:]:
        key, _, value = arg.partition("=")
        if key.strip() not in keywords:
            raise ScriptError(f"{name}: unknown argument {arg!r} in {line!r}")
        keywords[key.strip()] = _number(value, line)
    if any(v <= 0 for v in keywords.values()):
        raise ScriptError(f"{name}: a and v must be > 0 in {line!r}")
    return Statement(name, values, is_pose, tuple(sorted(keywords.items())))


def _split(args: str) -> list[str]:
    parts, depth, current = [], 0, ""
    for char in args:
        depth += (char == "[") - (char == "]")
        if char == "," and depth == 0:
            parts.append(current.strip())
            current = ""
        else:
            current += char
    if current.strip():
        parts.append(current.strip())
    return parts


def _number(text: str, line: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ScriptError(f"{text.strip()!r} is not a number in {line!r}") from None
