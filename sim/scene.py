"""Scenes: what the simulated rig looks at, and which effects it renders.

A scene TOML names the sample (a registered generator and its parameters), the
materials, the rig (a rig-config file and/or inline overrides of its fields),
how far the simulated rig stands off that config (``[as_built]``,
:mod:`sim.as_built`), the render scale, the radiometry and the list of effects; an effect's
parameters go in a table of the same name, which is only allowed when the
effect is listed. Every problem is reported at once, one line each, naming the
field, the value and what would be valid.

Example::

    effects = ["shadows", "noise"]

    [sample]
    generator = "bumps"
    depth_mm = 3.0
    materials = ["cloth"]
    params = { amplitude_mm = 1.0, spacing_mm = 8.0 }

    [materials.cloth]
    albedo = { kind = "noise", rgb = [0.7, 0.5, 0.3] }

    [noise]
    read_noise_e = 4.0
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from rig.config import RigConfig
from rig.errors import ConfigError
from rig.kinds import rig_kind
from rig.tomlfile import format_validation_error, read_toml
from sim.as_built import AsBuilt, AsBuiltSpec
from sim.materials import ImageAlbedo, MaterialSpec
from sim.samples import generator

__all__ = [
    "EFFECTS",
    "InterreflectionParams",
    "LaserParams",
    "LensDistortionParams",
    "NoiseParams",
    "Radiometry",
    "RenderSpec",
    "ResponseParams",
    "RigSpec",
    "SampleSpec",
    "Scene",
    "SceneSpec",
    "ShadowParams",
    "VignettingParams",
    "load_scene",
    "scene_from_dict",
]

Effect = Literal[
    "shadows",
    "specular",
    "laser",
    "noise",
    "saturation",
    "vignetting",
    "lens_distortion",
    "interreflection",
    "motion_timing",
    "response",
]
#: Every effect a scene may list.
EFFECTS: tuple[str, ...] = get_args(Effect)


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class SampleSpec(_Closed):
    generator: str = Field(description="a registered sample generator")
    depth_mm: float = Field(3.0, gt=0, le=100, description="depth of the holder's recess")
    margin_mm: float = Field(
        5.0, ge=0, le=100,
        description="how far the recess, and the sample filling it, reach past the measured "
        "square (holder.sample_mm) on every side: the recess walls, the shadows they cast and "
        "the gap at them stay out of the texel grid, as on a real holder",
    )  # fmt: skip
    materials: tuple[str, ...] = Field(("default",), min_length=1)
    params: dict[str, Any] = Field(default_factory=dict, description="the generator's options")


class RigSpec(_Closed):
    config: Path | None = Field(None, description="rig config TOML (default rig if absent)")
    kind: str | None = Field(
        None, description="the rig's kind (rig.kinds; its section's defaults unless given); "
        "default: the config's"
    )
    overrides: dict[str, Any] = Field(default_factory=dict, description="RigConfig fields")


class RenderSpec(_Closed):
    scale: float = Field(1.0, gt=0, le=4, description="image size and intrinsics factor")
    supersample: int = Field(
        1,
        ge=1,
        le=8,
        description="k: shade k×k points per pixel and average them, as a sensor integrates "
        "over its pixel's area (1: one point at the pixel centre; k² times the shading cost)",
    )


class Radiometry(_Closed):
    """Lamp power and sensor response.

    A lamp of relative intensity ``k`` has radiant intensity ``k ·
    intensity_w_sr``; a pixel reaches full scale at radiant exposure
    ``full_scale_exposure`` (radiance × exposure time, W·s/(sr·m²)).
    """

    intensity_w_sr: float = Field(10.0, gt=0)
    full_scale_exposure: float = Field(0.5, gt=0, description="W·s/(sr·m²) at full scale")
    exposure_s: float = Field(0.05, gt=0, description="default exposure")


class ShadowParams(_Closed):
    offset_mm: float = Field(1e-3, gt=0, le=1, description="shadow-ray start off the surface")


class LaserParams(_Closed):
    width_mm: float = Field(0.3, gt=0, description="Gaussian σ of the sheet's cross-profile")
    power_w: float = Field(0.005, gt=0)
    fan_deg: float = Field(60.0, gt=0, lt=180, description="opening angle of the sheet")


class NoiseParams(_Closed):
    full_well_e: float = Field(10000.0, gt=0, description="electrons at full scale")
    read_noise_e: float = Field(5.0, ge=0, description="read noise σ, electrons")
    seed: int = Field(0, ge=0)


class VignettingParams(_Closed):
    exponent: float = Field(4.0, ge=0, description="irradiance falls as cos^exponent")


class LensDistortionParams(_Closed):
    coefficients: tuple[float, float, float, float, float] | None = Field(
        None, description="Brown–Conrady (k1, k2, p1, p2, k3); default: each camera's dist"
    )


class ResponseParams(_Closed):
    """The camera's tone curve: value = full_scale · (linear / full_scale)^(1/gamma)."""

    gamma: float = Field(2.2, gt=0.2, le=5, description="1 is a linear camera")


class InterreflectionParams(_Closed):
    samples_per_pixel: int = Field(16, ge=1, le=4096)
    max_depth: int = Field(4, ge=3, le=32, description="path length (3 = one extra bounce)")


_PARAMS = {
    "shadows": ShadowParams,
    "laser": LaserParams,
    "noise": NoiseParams,
    "vignetting": VignettingParams,
    "lens_distortion": LensDistortionParams,
    "interreflection": InterreflectionParams,
    "response": ResponseParams,
}


class SceneSpec(_Closed):
    """The scene file, as validated."""

    name: str = "scene"
    sample: SampleSpec
    materials: dict[str, MaterialSpec] = Field(default_factory=lambda: {"default": MaterialSpec()})
    rig: RigSpec = RigSpec()
    render: RenderSpec = RenderSpec()
    radiometry: Radiometry = Radiometry()
    as_built: AsBuiltSpec = Field(
        AsBuiltSpec(), description="how far the simulated rig stands off its config"
    )
    effects: tuple[Effect, ...] = ()
    shadows: ShadowParams | None = None
    laser: LaserParams | None = None
    noise: NoiseParams | None = None
    vignetting: VignettingParams | None = None
    lens_distortion: LensDistortionParams | None = None
    interreflection: InterreflectionParams | None = None
    response: ResponseParams | None = None
    faults: dict[str, dict[str, Any]] = Field(
        default_factory=dict,
        description="per peer (turntable, lamp_bank, light_arc, laser, cameras) its fault table",
    )

    def problems(self) -> list[str]:
        """Cross-field problems pydantic's field checks cannot see."""
        problems = []
        if len(set(self.effects)) != len(self.effects):
            problems.append(f"effects: each effect once, got {list(self.effects)}")
        for name in _PARAMS:
            if getattr(self, name) is not None and name not in self.effects:
                problems.append(f"{name}: parameters given but {name!r} is not in effects")
        missing = [m for m in self.sample.materials if m not in self.materials]
        if missing:
            problems.append(
                f"sample.materials: {missing} not defined; defined are {sorted(self.materials)}"
            )
        return problems

    def params(self, effect: str) -> BaseModel:
        """The parameters of a listed effect (defaults when its table is absent)."""
        return getattr(self, effect) or _PARAMS[effect]()


@dataclass(frozen=True)
class Scene:
    """A validated scene: the spec, the rig it runs on, the generator's params.

    ``rig`` is the effective rig config: file + overrides, cameras scaled by
    ``render.scale`` and carrying the lens-distortion coefficients, so that
    ``rig.camera_model(id)`` describes the simulated images exactly when the
    rig is built to its config. ``as_built`` (None when it is) holds where the
    simulated rig's lamps and cameras stand off ``rig`` (``[as_built]``); the
    simulator renders with them, ``rig`` stays what the daemon is told.
    """

    spec: SceneSpec
    rig: RigConfig
    sample_params: BaseModel
    source: str
    as_built: AsBuilt | None = None

    def has(self, effect: str) -> bool:
        return effect in self.spec.effects


def _lines(prefix: tuple, err: ValidationError, model: type[BaseModel]) -> list[str]:
    where = ".".join(prefix)
    return [
        f"{where}.{line}" if where else line for line in format_validation_error("", err, model)
    ]


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for key, value in over.items():
        out[key] = (
            _merge(out[key], value)
            if isinstance(value, dict) and isinstance(out.get(key), dict)
            else value
        )
    return out


def _resolve(path: Path, base_dir: Path) -> Path:
    return path if path.is_absolute() else (base_dir / path)


def scene_from_dict(data: dict, *, source: str = "scene", base_dir: Path = Path()) -> Scene:
    """Validate a scene from its TOML data; relative paths resolve against ``base_dir``."""
    try:
        spec = SceneSpec.model_validate(data)
    except ValidationError as err:
        raise ConfigError(_report(source, _lines((), err, SceneSpec))) from err
    problems = spec.problems()
    try:
        gen = generator(spec.sample.generator)
    except ConfigError as err:
        raise ConfigError(_report(source, [f"sample.generator: {err}"])) from err
    params_data = dict(spec.sample.params)
    if isinstance(params_data.get("path"), str):
        params_data["path"] = str(_resolve(Path(params_data["path"]), base_dir))
    try:
        sample_params = gen.params_model.model_validate(params_data)
    except ValidationError as err:
        problems += _lines(("sample", "params"), err, gen.params_model)
        sample_params = None
    if gen.n_materials < len(spec.sample.materials):
        problems.append(
            f"sample.materials: generator {gen.name!r} uses {gen.n_materials} material(s), "
            f"got {len(spec.sample.materials)}"
        )
    rig = _rig(spec, base_dir, source, problems)
    if problems:
        raise ConfigError(_report(source, problems))
    materials = {
        name: m.model_copy(update={"albedo": m.albedo.model_copy(
            update={"path": _resolve(m.albedo.path, base_dir)})})
        if isinstance(m.albedo, ImageAlbedo) else m
        for name, m in spec.materials.items()
    }  # fmt: skip
    spec = spec.model_copy(update={"materials": materials})
    as_built = None if spec.as_built.exact else AsBuilt.draw(spec.as_built, rig)
    return Scene(spec=spec, rig=rig, sample_params=sample_params, source=source,
                 as_built=as_built)  # fmt: skip


def _rig(spec: SceneSpec, base_dir: Path, source: str, problems: list[str]) -> RigConfig | None:
    if spec.rig.config is not None:
        path = _resolve(spec.rig.config, base_dir)
        try:
            base = read_toml(path, "rig config")
        except ConfigError as err:
            problems.append(f"rig.config: {err}")
            return None
    else:
        base = {}  # the default rig of the kind
    data = _merge(base, spec.rig.overrides)
    if spec.rig.kind is not None:
        data["kind"] = spec.rig.kind
        try:
            section = rig_kind(spec.rig.kind).section
        except ConfigError as err:
            problems.append(f"rig.kind: {err}")
            return None
        if section is not None:  # the kind's section with its defaults
            data.setdefault(section, {})
    try:
        rig = RigConfig.model_validate(data)
    except ValidationError as err:
        problems += _lines(("rig",), err, RigConfig)
        return None
    return _cameras(rig, spec, problems)


def _cameras(rig: RigConfig, spec: SceneSpec, problems: list[str]) -> RigConfig:
    """Scale the cameras and give them the scene's lens distortion."""
    lens = spec.params("lens_distortion") if "lens_distortion" in spec.effects else None
    coeffs = lens.coefficients if lens is not None else None
    s = spec.render.scale
    cams = []
    for cam in rig.camera_arc.cameras:
        dist = cam.dist
        if lens is None and any(dist):
            problems.append(
                f"rig camera {cam.id}: dist {list(dist)} is non-zero but 'lens_distortion' "
                "is not in effects; list it or zero the camera's dist"
            )
        if coeffs is not None:
            if any(dist) and tuple(dist) != tuple(coeffs):
                problems.append(
                    f"lens_distortion.coefficients: {list(coeffs)} differ from camera "
                    f"{cam.id}'s dist {list(dist)}; they must be the same (or dist zero)"
                )
            dist = tuple(coeffs)
        width, height = max(1, round(cam.width * s)), max(1, round(cam.height * s))
        update = {
            "width": width,
            "height": height,
            "fx_px": cam.fx_px * width / cam.width,
            "fy_px": cam.fy_px * height / cam.height,
            "dist": dist,
        }
        if cam.cx_px is not None:
            update["cx_px"] = (cam.cx_px + 0.5) * width / cam.width - 0.5
        if cam.cy_px is not None:
            update["cy_px"] = (cam.cy_px + 0.5) * height / cam.height - 0.5
        cams.append(cam.model_copy(update=update))
    arc = rig.camera_arc.model_copy(update={"cameras": tuple(cams)})
    return rig.model_copy(update={"camera_arc": arc})


def _report(source: str, problems: list[str]) -> str:
    lines = "\n".join(f"  - {p}" for p in problems)
    return f"scene {source}: {len(problems)} problem(s)\n{lines}"


def load_scene(path: str | Path, *, kind: str | None = None) -> Scene:
    """Read and validate a scene TOML file; every problem names its field.

    ``kind`` (``wang``, ``bonn``, ``virtex``) replaces the scene's ``rig.kind``.

    Raises
    ------
    ConfigError
        The file is missing, not TOML, or invalid; the message lists each
        problem as ``field: what is wrong (got value)``.
    """
    path = Path(path)
    data = read_toml(path, "scene")
    if kind is not None and isinstance(data.get("rig", {}), dict):
        data["rig"] = {**data.get("rig", {}), "kind": kind}
    return scene_from_dict(data, source=str(path), base_dir=path.parent)
