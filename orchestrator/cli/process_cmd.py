"""`rig process`: processing stages over a recorded archive, on Dask."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from orchestrator.cli.common import console, flagged_lines, prepare_folder, quiet_dask_logs
from rig.errors import ConfigError, RigError

__all__ = ["register", "write_mdf_previews", "write_ps_previews"]


def write_ps_previews(archive_path: Path, out: Path) -> list[Path]:
    """Normal map, albedo and shaded height PNGs of every view in ``material/ps``."""
    from processing.photometric import albedo_preview, hillshade_preview, normal_map_preview
    from rig.archive import Archive
    from rig.interchange import write_image

    out.mkdir(parents=True, exist_ok=True)
    written = []
    with Archive.open(archive_path, mode="r") as archive:
        group = archive.material["ps"]
        sample_mm = archive.rig_config["holder"]["sample_mm"]
        for name in sorted(group):
            view = group[name]
            valid = view["valid"][:]
            height = view["height_mm"][:]
            images = {
                "normals": normal_map_preview(view["normals"][:]),
                "albedo": albedo_preview(view["albedo"][:], valid=valid),
                "height": hillshade_preview(height, pitch_mm=sample_mm / height.shape[0]),
            }
            for kind, image in images.items():
                written.append(write_image(out / f"{name}_{kind}.png", image))
    return written


def write_mdf_previews(archive_path: Path, out: Path) -> list[Path]:
    """Each view's MDF as a grey PNG: black at the reference plane, white at the 99th percentile,
    dark red where unseen (−1)."""
    import numpy as np

    from rig.archive import Archive
    from rig.interchange import write_image

    out.mkdir(parents=True, exist_ok=True)
    written = []
    with Archive.open(archive_path, mode="r") as archive:
        group = archive.material["mdf"]
        distance = group["distance_mm"][:]
        names = group.attrs["views"]
    seen = distance >= 0
    top = float(np.percentile(distance[seen], 99)) if seen.any() else 1.0  # outliers clip
    for name, d, s in zip(names, distance, seen, strict=True):
        grey = np.round(255.0 * np.clip(d / max(top, 1e-9), 0.0, 1.0)).astype(np.uint8)
        image = np.where(s[..., None], grey[..., None], np.array([96, 0, 0], np.uint8))
        written.append(write_image(out / f"{name}_mdf.png", image))
    return written


def archive_flagged_lines(archive_path: Path) -> list[str]:
    """What the archive's step table flags: frames that did not record their step's state."""
    from rig.archive import Archive
    from rig.frame_check import flag_summary, flags_of

    with Archive.open(archive_path, mode="r") as archive:
        return flagged_lines(flag_summary(flags_of(archive.step_table())))


#: --views and --lights as the btf stage names them (processing.offline.btf.DIRECTIONS)
_DIRECTIONS = {"nominal": "nominal", "per-texel": "per texel", "model": "model"}
#: the stages with preview PNGs, and what writes them
_PREVIEWS = {"ps": write_ps_previews, "mdf": write_mdf_previews}


def process(
    archive: Annotated[Path, typer.Argument(help="session archive")],
    stages: Annotated[str, typer.Option("--stages", help="comma-separated, e.g. ps")] = "ps",
    size: Annotated[int, typer.Option(min=8, max=4096, help="texels per side of the maps")] = 128,
    scheduler: Annotated[
        str | None,
        typer.Option("--scheduler", help="a running Dask scheduler (default: local cluster)"),
    ] = None,
    components: Annotated[
        int, typer.Option(min=1, max=64, help="btf: PCA components per view slot")
    ] = 8,
    workers: Annotated[int, typer.Option(min=1, help="local cluster threads")] = 2,
    previews: Annotated[
        Path | None,
        typer.Option("--previews", help="folder for preview PNGs (default: ARCHIVE_previews)"),
    ] = None,
    raw: Annotated[
        bool,
        typer.Option(
            "--raw",
            help="ps, btf: frames as recorded, without the calibration's response "
            "linearisation and lamp flat fields (btf: nor the near lamps' irradiance "
            "per texel)",
        ),
    ] = False,
    flat_beyond_mm: Annotated[
        float,
        typer.Option(
            "--flat-beyond-mm",
            min=0.0,
            help="ps: the sample is flat beyond this wavelength (mm); its height keeps "
            "no longer shape (0: the height as integrated)",
        ),
    ] = 15.0,
    views: Annotated[
        str,
        typer.Option(
            "--views",
            help="btf: nominal (each texel at its view slot's direction), per-texel (each "
            "texel's own direction through the calibrated camera, resampled onto the plan's "
            "views; texels outside the measured directions are kept and counted) or model "
            "(each texel scaled by how much the fitted PBR model changes between its own "
            "direction and the slot's; run the pbr stage at this --size first)",
        ),
    ] = "nominal",
    lights: Annotated[
        str,
        typer.Option(
            "--lights",
            help="btf: per-texel (the default: each texel's own direction to the placed lamp,"
            " resampled onto the plan's lights; texels outside the measured directions are "
            "kept and counted), nominal (each texel at its capture's light direction) or model "
            "(each texel scaled by how much the fitted PBR model changes between its own "
            "direction and the plan's; run the pbr stage at this --size first)",
        ),
    ] = "per-texel",
) -> None:
    """Run processing stages over an archive into its material/ group.

    Re-running a stage replaces its output atomically; a failed run leaves the
    previous output as it was. Stages: ps (photometric stereo: normals, albedo,
    height on the sample's texel grid, with preview PNGs); btf (registered
    normtextures of every view slot, compressed by per-view PCA, --components);
    mdf (the mesostructure distance function of the laser scans, with previews);
    pbr (the BTF fitted per texel by a glTF PBR material — base colour, roughness,
    specular, sheen, anisotropy, normal, height — with its fit error; needs btf,
    which may run first in the same command; the fit keeps the BTF's texel grid).
    A stage that can use none of its frames (all flagged: saturated, black…) is
    skipped with the reason, the others still run, and the exit code is 1. A
    stage the session captured nothing for (btf or mdf of a PS-only rig) is
    skipped with the reason too, and is no failure.
    Frames the session flagged as not recording their step's state (the laser
    tilt, the lamp, the axes) are listed; mdf leaves out those never re-captured.
    When the archive's calibration has them, ps and btf frames are linearised
    by the camera's response curve and divided by their lamp's flat field; btf
    texels are divided by their near lamp's irradiance and resampled from their
    own light directions onto the plan's (calibrated or nominal lamp positions;
    --lights). --raw: none of it; the material records what was applied.
    """
    quiet_dask_logs()
    from processing.offline import STAGES, run_stages

    names = [s.strip() for s in stages.split(",") if s.strip()]
    unknown = [n for n in names if n not in STAGES]
    if unknown or not names:
        raise ConfigError(
            f"--stages {stages!r}: unknown stage(s) {unknown}; valid are {sorted(STAGES)}"
        )
    if previews is not None and any(n in _PREVIEWS for n in names):
        prepare_folder(previews, f"--previews {previews}")
    for option, value in (("--views", views), ("--lights", lights)):
        if value not in _DIRECTIONS:
            raise ConfigError(f"{option} {value!r}: valid are {', '.join(_DIRECTIONS)}")
        if value == "model" and "btf" in names and "pbr" in names:
            raise ConfigError(
                f"{option} model moves the BTF by the fitted PBR model, which --stages "
                f"{stages} would fit after it: run --stages btf,pbr first, then --stages btf "
                f"{option} model"
            )
    flat = flat_beyond_mm or None
    options = {
        "btf": {"size": size, "components": components, "raw": raw, "views": _DIRECTIONS[views],
                "lights": _DIRECTIONS[lights]},
        "ps": {"size": size, "raw": raw, "flat_beyond_mm": flat},
        "mdf": {"size": size}, "pbr": {},
    }  # fmt: skip
    chosen = [STAGES[n](**options[n]) for n in names]
    columns = (
        TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
        TimeElapsedColumn(),
    )  # fmt: skip
    with Progress(*columns, console=console) as bar:
        tasks: dict[str, int] = {}

        def progress(stage: str, done: int, total: int) -> None:
            if stage not in tasks:
                tasks[stage] = bar.add_task(stage, total=total)
            bar.update(tasks[stage], completed=done)

        runs = run_stages(archive, chosen, scheduler=scheduler, workers=workers, progress=progress)
    _report(runs, archive, previews or archive.with_name(f"{archive.stem}_previews"))


def _report(runs, archive: Path, previews: Path) -> None:
    """Say what each stage run wrote or why it was skipped, list the archive's flagged
    frames, write the previews into the folder ``previews``; a ``RigError`` when a
    stage that had frames to use was skipped."""
    for run in runs:
        if run.skipped is not None:
            console.print(f"[yellow]{run.stage}: skipped[/yellow] — {escape(run.skipped)}")
            continue
        detail = ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                           for k, v in run.summary.items())  # fmt: skip
        console.print(escape(f"{run.stage}: {run.items} item(s) → material/{run.stage} ({detail})"))
    for line in archive_flagged_lines(archive):
        console.print(escape(line), style="yellow")
    for run in runs:
        if run.skipped is None and run.stage in _PREVIEWS:
            for path in _PREVIEWS[run.stage](archive, previews):
                console.print(escape(f"wrote {path}"))
    skipped = [run.stage for run in runs if run.skipped is not None and not run.absent]
    if skipped:
        raise RigError(
            f"{len(skipped)} of {len(runs)} stage(s) skipped: {', '.join(skipped)} "
            "(the reasons are above); the other stages' results are in material/"
        )


def register(app: typer.Typer) -> None:
    """Add `rig process` to ``app``."""
    app.command()(process)
