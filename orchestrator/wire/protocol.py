"""The daemon's messages: control requests and replies, events, frames and results.

Every message is JSON (never pickle) checked by a closed pydantic model
(``extra="forbid"``), with a size limit on every part. Arrays travel as a JSON
header (dtype, shape, ids) followed by the raw buffer, sent with
``copy=False``. A message that fails a check raises ``MessageError`` with a
code, the offending field and what would be valid; the daemon turns it into an
error reply and goes on.

Control (ROUTER; clients REQ or DEALER): one body part
``{"id": str, "command": str, "args": {...}}``; the reply is
``{"id", "ok", "result" | "error": {"code", "message", "field"}}``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError

from rig.errors import RigError

__all__ = [
    "ARGS_MODELS",
    "FRAME_DTYPES",
    "MAX_CONTROL_BYTES",
    "MAX_FRAME_BYTES",
    "MAX_HEADER_BYTES",
    "MAX_INT_DIGITS",
    "MAX_JSON_DEPTH",
    "MAX_PLAN_PAIRS",
    "ArraySpec",
    "FrameHeader",
    "MessageError",
    "Request",
    "ResultHeader",
    "decode_array",
    "decode_frame",
    "decode_json",
    "decode_request",
    "decode_result",
    "encode_error",
    "encode_event",
    "encode_frame",
    "encode_reply",
    "encode_result",
    "parse_request",
    "request_id",
    "validate_request",
]

#: Largest control request or reply: all its body parts together (a plan's TOML goes inside).
MAX_CONTROL_BYTES = 2 * 1024 * 1024
#: Deepest nesting of arrays and objects in a JSON message (a request needs 3).
MAX_JSON_DEPTH = 32
#: Digits an integer in a message may have (2**128 has 39); Python refuses past 4300.
MAX_INT_DIGITS = 40
#: Most (view, light) pairs in one plan: three times a full H1 × H1 BTF (6,561 pairs).
MAX_PLAN_PAIRS = 20_000
#: Largest JSON header of a frame or result.
MAX_HEADER_BYTES = 64 * 1024
#: Largest pixel buffer of one frame (a 16-bit 8k × 8k RGB frame is 384 MiB).
MAX_FRAME_BYTES = 512 * 1024 * 1024
#: Pixel and result types that may travel.
FRAME_DTYPES = ("uint8", "uint16", "float32", "float64", "int32", "int64")
_MAX_PLAN_CHARS = 1024 * 1024


class MessageError(RigError):
    """A message failed a check: ``code``, ``field`` (dotted path or None), message."""

    def __init__(self, code: str, message: str, field: str | None = None):
        self.code = code
        self.field = field
        self.message = message
        super().__init__(f"{code}: {message}")

    def to_json(self) -> dict:
        return {"code": self.code, "message": self.message, "field": self.field}


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


Ident = Annotated[str, Field(min_length=1, max_length=128)]


def _no_nul(path: str) -> str:
    if "\x00" in path:
        raise ValueError("holds a NUL byte, which no path can hold")
    return path


#: A path the daemon opens: checked here, so that the OS never sees a NUL byte.
PathText = Annotated[str, Field(max_length=4096), AfterValidator(_no_nul)]


class NoArgs(_Closed):
    pass


class SubmitArgs(_Closed):
    plan_toml: str = Field(min_length=1, max_length=_MAX_PLAN_CHARS)
    source: str = Field("<plan>", max_length=4096, description="where the plan came from")
    archive: PathText | None = Field(None, description="overrides output.archive")


class ResumeArgs(_Closed):
    archive: PathText | None = Field(
        None, description="continue a crashed session from its archive"
    )
    config_toml: str | None = Field(
        None,
        max_length=_MAX_PLAN_CHARS,
        description="with archive: the rig config (TOML text) whose connections to use; "
        "default the daemon's",
    )
    config_source: str = Field("<rig config>", max_length=4096, description="where it came from")


class CalibrateArgs(_Closed):
    target: Literal["cameras", "lamps", "laser", "response"]


#: command → the model of its ``args``.
ARGS_MODELS: dict[str, type[_Closed]] = {
    "submit": SubmitArgs,
    "status": NoArgs,
    "pause": NoArgs,
    "resume": ResumeArgs,
    "abort": NoArgs,
    "calibrate": CalibrateArgs,
    "shutdown": NoArgs,
}


class _Envelope(_Closed):
    id: Ident
    command: Annotated[str, Field(max_length=64)]
    args: dict[str, Any] = Field(default_factory=dict)


class Request(_Closed):
    """A validated control request."""

    id: str
    command: str
    args: Any


def _field(loc: Sequence) -> str:
    return ".".join(str(p) for p in loc)


def _first_problem(err: ValidationError, prefix: str = "") -> MessageError:
    problem = err.errors()[0]
    field = prefix + _field(problem["loc"])
    kind = problem["type"]
    if kind == "extra_forbidden":
        return MessageError("invalid", f"unknown field {field!r}", field)
    if kind == "missing":
        return MessageError("invalid", f"field {field!r} is missing", field)
    return MessageError("invalid", f"field {field!r}: {problem['msg']}", field)


def decode_json(body: bytes, *, limit: int, what: str) -> dict:
    """Parse a JSON object of at most ``limit`` bytes, nested at most ``MAX_JSON_DEPTH``."""
    if len(body) > limit:
        raise MessageError("too_large", f"{what} has {len(body)} bytes; the limit is {limit}")
    too_deep = MessageError(
        "too_deep", f"{what} nests arrays or objects deeper than the limit of {MAX_JSON_DEPTH}"
    )
    try:
        data = json.loads(body, parse_int=_integer, parse_float=_finite, parse_constant=_finite)
    except _BadNumber as err:
        raise MessageError("malformed", f"{what} {err}") from None
    except ValueError as err:  # JSONDecodeError and UnicodeDecodeError are ValueErrors
        raise MessageError("malformed", f"{what} is not valid UTF-8 JSON: {err}") from None
    except RecursionError:  # the parser gave up first: far deeper than the limit
        raise too_deep from None
    if not isinstance(data, dict):
        raise MessageError("malformed", f"{what} must be a JSON object, got {type(data).__name__}")
    if _depth_exceeds(data, MAX_JSON_DEPTH):
        raise too_deep
    return data


class _BadNumber(ValueError):
    """A number in a message that Python cannot hold, or that is not finite."""


def _integer(text: str) -> int:
    digits = len(text.lstrip("-"))
    if digits > MAX_INT_DIGITS:
        raise _BadNumber(f"holds an integer of {digits} digits; the limit is {MAX_INT_DIGITS}")
    return int(text)


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise _BadNumber(f"holds the number {text[:32]!r}, which is not finite")
    return value


def _depth_exceeds(data, limit: int) -> bool:
    """True if ``data`` nests lists or dicts more than ``limit`` deep (without recursion)."""
    level = [data]
    for _ in range(limit):
        level = [
            child
            for node in level
            for child in (node.values() if isinstance(node, dict) else node)
            if isinstance(child, dict | list)
        ]
        if not level:
            return False
    return True


def request_id(data: dict) -> str | None:
    """The request id of a decoded body, if it has a valid one (for error replies)."""
    rid = data.get("id")
    return rid if isinstance(rid, str) and 0 < len(rid) <= 128 else None


def decode_request(body: bytes) -> dict:
    """The JSON object of one control request body; ``MessageError`` if it is none."""
    return decode_json(body, limit=MAX_CONTROL_BYTES, what="the request")


def parse_request(body: bytes) -> Request:
    """Validate one control request body; raise ``MessageError`` naming the problem."""
    return validate_request(decode_request(body))


def validate_request(data: dict) -> Request:
    """Check a request decoded by ``decode_request``; ``MessageError`` naming the field."""
    try:
        envelope = _Envelope.model_validate(data)
    except ValidationError as err:
        raise _first_problem(err) from None
    model = ARGS_MODELS.get(envelope.command)
    if model is None:
        raise MessageError(
            "unknown_command",
            f"unknown command {envelope.command!r}; valid are {sorted(ARGS_MODELS)}",
            "command",
        )
    try:
        args = model.model_validate(envelope.args)
    except ValidationError as err:
        raise _first_problem(err, "args.") from None
    return Request(id=envelope.id, command=envelope.command, args=args)


def _dumps(data: dict) -> bytes:
    return json.dumps(data, allow_nan=False, separators=(",", ":")).encode()


def encode_reply(request_id: str | None, result: dict) -> bytes:
    return _dumps({"id": request_id, "ok": True, "result": result})


def encode_error(request_id: str | None, error: MessageError) -> bytes:
    return _dumps({"id": request_id, "ok": False, "error": error.to_json()})


def encode_event(topic: str, seq: int, time: float, payload: dict) -> list[bytes]:
    """An event as ``[topic, json]``; ``seq`` counts every event the daemon published."""
    return [topic.encode(), _dumps({"seq": seq, "time": time, "topic": topic, **payload})]


# -- arrays ---------------------------------------------------------------------------------


class ArraySpec(_Closed):
    dtype: Literal[FRAME_DTYPES]  # type: ignore[valid-type]
    shape: tuple[Annotated[int, Field(ge=1, le=1 << 20)], ...] = Field(max_length=4)

    @property
    def nbytes(self) -> int:
        return math.prod(self.shape) * np.dtype(self.dtype).itemsize


class FrameHeader(_Closed):
    """What travels with a frame to the workers."""

    frame_id: int = Field(ge=0)
    session: Ident
    step: int = Field(ge=0)
    kind: Annotated[str, Field(max_length=32)]
    camera: Ident
    sub: int = Field(ge=0)
    exposure_s: float = Field(gt=0)
    timestamp: float
    array: ArraySpec
    #: the session's archive, for live stages that read config, plan and steps from it
    archive: PathText | None = None


class NamedArray(ArraySpec):
    name: Annotated[str, Field(min_length=1, max_length=64)]


class ResultHeader(_Closed):
    """What a worker sends back: ``hello`` on start, ``heartbeat``, or a ``result``."""

    kind: Literal["hello", "heartbeat", "result", "error"]
    worker: Ident
    stage: Annotated[str, Field(max_length=64)]
    frame_id: int | None = Field(None, ge=0)
    session: str | None = Field(None, max_length=128)
    step: int | None = Field(None, ge=0)
    camera: str | None = Field(None, max_length=128)
    sub: int | None = Field(None, ge=0)
    arrays: tuple[NamedArray, ...] = Field((), max_length=32)
    message: str | None = Field(None, max_length=4096)


def decode_array(spec: ArraySpec, buffer, *, what: str) -> np.ndarray:
    """A read-only array view of ``buffer`` after checking its size against ``spec``."""
    view = memoryview(buffer)
    if view.nbytes != spec.nbytes:
        raise MessageError(
            "invalid",
            f"{what}: buffer has {view.nbytes} bytes, dtype {spec.dtype} × shape "
            f"{list(spec.shape)} needs {spec.nbytes}",
            "array",
        )
    return np.frombuffer(view, dtype=spec.dtype).reshape(spec.shape)


def _validate(model: type[_Closed], data: dict) -> Any:
    try:
        return model.model_validate(data)
    except ValidationError as err:
        raise _first_problem(err) from None


def encode_frame(header: FrameHeader, image: np.ndarray) -> list:
    """``[header json, pixel buffer]``; send with ``copy=False``."""
    return [_dumps(header.model_dump(mode="json")), np.ascontiguousarray(image).data]


def decode_frame(parts: Sequence) -> tuple[FrameHeader, np.ndarray]:
    """Check and unpack a frame message (parts may be bytes or ``zmq.Frame``)."""
    if len(parts) != 2:
        raise MessageError("malformed", f"a frame has 2 parts (header, pixels), got {len(parts)}")
    header_bytes, pixels = (_bytes_like(p) for p in parts)
    if memoryview(pixels).nbytes > MAX_FRAME_BYTES:
        raise MessageError("too_large", f"frame pixels exceed {MAX_FRAME_BYTES} bytes")
    data = decode_json(bytes(header_bytes), limit=MAX_HEADER_BYTES, what="the frame header")
    header = _validate(FrameHeader, data)
    return header, decode_array(header.array, pixels, what=f"frame {header.frame_id}")


def encode_result(header: ResultHeader, arrays: Sequence[np.ndarray] = ()) -> list:
    parts = [_dumps(header.model_dump(mode="json", exclude_none=True))]
    parts.extend(np.ascontiguousarray(a).data for a in arrays)
    return parts


def decode_result(parts: Sequence) -> tuple[ResultHeader, dict[str, np.ndarray]]:
    """Check and unpack a worker message into its header and named arrays."""
    if not 1 <= len(parts) <= 17:
        raise MessageError("malformed", f"a result has 1 + up to 16 parts, got {len(parts)}")
    data = decode_json(
        bytes(_bytes_like(parts[0])), limit=MAX_HEADER_BYTES, what="the result header"
    )
    header = _validate(ResultHeader, data)
    if len(header.arrays) != len(parts) - 1:
        raise MessageError(
            "invalid",
            f"the header lists {len(header.arrays)} arrays but {len(parts) - 1} buffers came",
            "arrays",
        )
    if header.kind == "result" and header.frame_id is None:
        raise MessageError("invalid", "a result needs frame_id", "frame_id")
    arrays = {}
    for spec, buffer in zip(header.arrays, parts[1:], strict=True):
        if spec.nbytes > MAX_FRAME_BYTES:
            raise MessageError("too_large", f"result array {spec.name!r} is too large")
        arrays[spec.name] = decode_array(spec, _bytes_like(buffer), what=f"array {spec.name!r}")
    return header, arrays


def _bytes_like(part):
    # zmq.Frame exposes its data as ``buffer``; bytes and memoryviews pass through.
    return getattr(part, "buffer", part)
