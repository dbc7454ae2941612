"""`rig export FORMAT ARCHIVE --out PATH`: a session's frames, normtextures and
material in the formats other tools read (``docs/interchange.md``).

Every export opens the archive read-only, writes into a hidden folder next to
``--out`` and renames it into place when complete, so a failed export leaves
nothing half-written; an existing ``--out`` is replaced only with
``--overwrite``, and only when it is an earlier export of this project (its
manifest, or a ``.glb``'s generator, says so).
"""

from __future__ import annotations

import contextlib
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from orchestrator.cli.common import PLAIN_HELP, console
from rig.errors import ConfigError

__all__ = ["app"]

app = typer.Typer(
    help="Write frames, normtextures or material in other tools' formats.",
    no_args_is_help=True,
    rich_markup_mode=PLAIN_HELP,
)

_Archive = Annotated[Path, typer.Argument(help="session archive", show_default=False)]
_Out = Annotated[Path, typer.Option("--out", help="output folder to create")]
_Overwrite = Annotated[
    bool, typer.Option("--overwrite", help="replace --out if it is an earlier btfrig export")
]
_View = Annotated[
    str | None,
    typer.Option("--view", help="the PS view's name (default: the most frontal one)"),
]


def _check_archive(archive: Path) -> None:
    if not (archive / "zarr.json").is_file() or not (archive / "log").is_dir():
        raise ConfigError(f"{archive}: not a session archive (no zarr.json and log/ there)")


@contextlib.contextmanager
def _export_to(out: Path, archive: Path, *, overwrite: bool, folder: bool = True) -> Iterator[Path]:
    """A fresh hidden folder (or file path) that becomes ``out`` when the block succeeds;
    a failed write (a full disk) is an InterchangeWriteError naming ``out``."""
    from rig.archive import overlaps_archive
    from rig.interchange import EXPORTED_BY, MANIFEST, InterchangeWriteError, is_export

    if overlaps_archive(out, archive):
        raise ConfigError(f"--out {out}: lies in or around the archive {archive}; give another")
    if out.exists() or out.is_symlink():
        if not overwrite:
            raise ConfigError(f"--out {out}: already exists; give a new path or --overwrite")
        if not is_export(out):
            raise ConfigError(
                f"--out {out}: exists and is not an earlier btfrig export (no {MANIFEST} "
                f'marked "exported_by": "{EXPORTED_BY}", nor a .glb btfrig generated); '
                "not replacing it"
            )
    if not out.parent.is_dir():
        raise ConfigError(f"--out {out}: folder {out.parent} does not exist")
    tmp = out.with_name(f".{out.name}.exporting")
    _remove(tmp)
    if folder:
        tmp.mkdir()
    try:
        yield tmp
        _remove(out)
        tmp.rename(out)
    except (OSError, InterchangeWriteError) as err:  # a full disk, a folder not writable
        what = err if isinstance(err, InterchangeWriteError) else (
            f"writing {err.filename + ' ' if err.filename else ''}failed: {err.strerror or err}"
        )  # fmt: skip
        raise InterchangeWriteError(f"--out {out}: {what}; nothing was written there") from err
    finally:
        _remove(tmp)


def _remove(path: Path) -> None:
    if path.is_dir():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


@contextlib.contextmanager
def _bar(description: str) -> Iterator[Callable[[int, int], None]]:
    columns = (TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn())  # fmt: skip
    with Progress(*columns, console=console, transient=True) as bar:
        task = bar.add_task(description, total=None)
        yield lambda done, total: bar.update(task, completed=done, total=total)


@app.command()
def material(
    archive: _Archive,
    out: Annotated[Path, typer.Option("--out", help="material store to create (M.zarr)")],
) -> None:
    """The material without the frames, as a store rig view reads.

    Its btf, ps, mdf and pbr groups, the sample's size and the calibration's
    provenance.
    """
    from rig.archive import overlaps_archive
    from rig.material import export_material

    if overlaps_archive(out, archive):
        raise ConfigError(f"--out {out}: lies in or around the archive {archive}; give another")
    if not (archive / "zarr.json").is_file() or not (archive / "material").is_dir():
        raise ConfigError(f"{archive}: not a session archive (no zarr.json and material/ there)")
    if out.exists():
        raise ConfigError(f"{out}: already exists; give --out a new path")
    written = export_material(archive, out)
    console.print(f"material store: {written}")


def _export_frames(fmt: str, what: str, archive: Path, out: Path, overwrite: bool) -> None:
    """Every frame of ``archive`` as ``fmt`` files (``what``, for the report) in ``out``."""
    from rig.interchange import export_frames

    _check_archive(archive)
    with _export_to(out, archive, overwrite=overwrite) as tmp, _bar(f"{fmt} frames") as bar:
        manifest = export_frames(archive, tmp, fmt, progress=bar)
    console.print(escape(f"wrote {out} ({what}, {manifest.name} lists them)"))


@app.command()
def png16(archive: _Archive, out: _Out, overwrite: _Overwrite = False) -> None:
    """Every recorded frame, raw, as 16-bit PNG.

    A manifest lists each frame's directions, camera, lamp and exposure.
    """
    _export_frames("png16", "16-bit PNG", archive, out, overwrite)


@app.command()
def tiff(archive: _Archive, out: _Out, overwrite: _Overwrite = False) -> None:
    """Every recorded frame, raw, as TIFF.

    A manifest lists each frame's directions, camera, lamp and exposure.
    """
    _export_frames("tiff", "TIFF", archive, out, overwrite)


@app.command()
def exr(archive: _Archive, out: _Out, overwrite: _Overwrite = False) -> None:
    """Every recorded frame, raw, as 32-bit float OpenEXR.

    A manifest lists each frame's directions, camera, lamp and exposure.
    """
    _export_frames("exr", "32-bit float OpenEXR", archive, out, overwrite)


@app.command()
def ubo2003(
    archive: _Archive,
    out: _Out,
    from_material: Annotated[
        bool,
        typer.Option("--from-material", help="the PCA reconstruction of material/btf instead"),
    ] = False,
    size: Annotated[
        int, typer.Option(min=8, max=4096, help="texels per side when frames are registered")
    ] = 128,
    white: Annotated[
        float | None,
        typer.Option(
            min=1e-9,
            help="linear value written as 255, kept in the manifest (default: an imported "
            "set's own, else the brightest 0.1 % of the most frontal view slot)",
        ),
    ] = None,
    overwrite: _Overwrite = False,
) -> None:
    """The normtextures in the Bonn UBO2003 layout (8-bit sRGB PNG).

    An imported archive's frames are written as they are; a captured session's
    are registered onto --size texels (flagged captures become listed gaps);
    --from-material writes the compressed BTF's reconstruction instead.
    """
    from orchestrator.cli.export_sources import btf_source
    from rig.interchange import write_ubo2003

    _check_archive(archive)
    with (
        btf_source(archive, from_material=from_material, size=size) as source,
        _export_to(out, archive, overwrite=overwrite) as tmp,
        _bar("ubo2003") as bar,
    ):
        manifest = write_ubo2003(
            tmp, source.views_deg, source.lights_deg, source.normtexture,
            white=source.auto_white() if white is None else white,
            manifest=source.manifest, progress=bar,
        )  # fmt: skip
    n_views, n_lights = len(source.views_deg), len(source.lights_deg)
    console.print(escape(f"wrote {out} ({n_views} views × {n_lights} lights, {manifest.name})"))


@app.command()
def maps(archive: _Archive, out: _Out, view: _View = None, overwrite: _Overwrite = False) -> None:
    """The photometric-stereo maps for DCC tools and game engines.

    albedo.png (sRGB), normal.png (16-bit, OpenGL convention: +Y up),
    height.png (16-bit) and height.exr (float mm), valid.png; the manifest
    holds the height's mm scale and the sample's size.
    """
    from orchestrator.cli.export_sources import ps_maps
    from rig.interchange import write_maps

    _check_archive(archive)
    maps_, sample_mm, manifest = ps_maps(archive, view)
    with _export_to(out, archive, overwrite=overwrite) as tmp:
        write_maps(tmp, maps_, sample_mm=sample_mm, manifest=manifest)
    console.print(escape(f"wrote {out} (view {manifest['view']}, {maps_.normal.shape[0]}² texels)"))


@app.command()
def gltf(
    archive: _Archive,
    out: Annotated[Path, typer.Option("--out", help="the .glb file to create")],
    view: _View = None,
    mesh: Annotated[
        Path | None, typer.Option("--mesh", help="a mesh file with UVs instead of the plane")
    ] = None,
    overwrite: _Overwrite = False,
) -> None:
    """A binary glTF (.glb) of the sample with its measured material.

    A plane of the sample's size in metres (or --mesh, a mesh file with UVs). With
    the material's PBR fit (`rig process --stages pbr`) and no --view: its maps —
    base colour, roughness (metallic 0), normal, KHR_materials_specular,
    KHR_materials_sheen and KHR_materials_anisotropy — and the fit's error in
    asset.extras.btfrig. Otherwise the PS maps of --view (default the most frontal):
    base colour = the albedo, normal texture (8-bit, glTF's OpenGL convention),
    metallic 0, roughness 1.
    """
    from orchestrator.cli.export_sources import pbr_maps, ps_maps
    from rig.interchange import pbr_textures, write_glb, write_pbr_glb
    from rig.material import read_material

    _check_archive(archive)
    if out.suffix.lower() != ".glb":
        raise ConfigError(f"--out {out}: a binary glTF needs the suffix .glb")
    if view is None and read_material(archive).pbr is not None:
        fitted, sample_mm, manifest = pbr_maps(archive)
        with _export_to(out, archive, overwrite=overwrite, folder=False) as tmp:
            write_pbr_glb(tmp.with_suffix(".glb"), pbr_textures(fitted), sample_mm=sample_mm,
                          mesh=mesh, manifest=manifest)  # fmt: skip
            tmp.with_suffix(".glb").rename(tmp)
        fit = manifest["fit"]
        console.print(escape(f"wrote {out} (PBR fit, {fit['psnr_db']:.1f} dB against the BTF, "
                             f"{sample_mm:g} mm plane)"))  # fmt: skip
        return
    maps_, sample_mm, manifest = ps_maps(archive, view)
    with _export_to(out, archive, overwrite=overwrite, folder=False) as tmp:
        glb = tmp.with_suffix(".glb")  # write_glb wants the suffix
        try:
            write_glb(glb, maps_, sample_mm=sample_mm, mesh=mesh)
            glb.rename(tmp)
        finally:
            glb.unlink(missing_ok=True)
    console.print(escape(f"wrote {out} (view {manifest['view']}, {sample_mm:g} mm plane)"))


@app.command()
def materialx(archive: _Archive, out: _Out, overwrite: _Overwrite = False) -> None:
    """The PBR fit (rig process --stages pbr) as a MaterialX material.

    material.mtlx (a standard_surface) and its PNG textures (colour maps sRGB, the
    others raw), with a manifest of the fit's error against the BTF; needs the
    materialx package (pip install 'btfrig[export]').
    """
    from orchestrator.cli.export_sources import pbr_maps
    from rig.interchange import write_manifest, write_materialx

    _check_archive(archive)
    fitted, _, manifest = pbr_maps(archive)
    with _export_to(out, archive, overwrite=overwrite) as tmp:
        document = write_materialx(tmp, fitted)
        write_manifest(tmp, {**manifest, "document": document.name})
    fit = manifest["fit"]
    console.print(escape(f"wrote {out} ({document.name}, {fit['psnr_db']:.1f} dB against the BTF)"))


@app.command()
def web(
    materials: Annotated[
        list[Path], typer.Argument(help="session archives or material stores", show_default=False)
    ],
    out: Annotated[Path, typer.Option("--out", help="the site's folder to create")],
    max_texels: Annotated[
        int, typer.Option(min=8, max=1024, help="texels per side each page loads at most")
    ] = 256,
    overwrite: _Overwrite = False,
) -> None:
    """A static web site that draws the materials in the browser.

    One page per material draws its measured BTF (per-view PCA, the renderer's
    nearest-four blends) or its PBR fit on the built-in meshes in WebGL2: drag to
    orbit, shift-drag to move the light, exposure slider, BTF/PBR toggle. index.html
    lists them with a thumbnail, size, sampling, capture date and fit error. Works
    offline, from a file or any static server; needs `rig process --stages btf,pbr`.
    """
    from orchestrator.web_site import write_site

    for material in materials:
        if not (material / "zarr.json").is_file():
            raise ConfigError(f"{material}: not a session archive or material store (no zarr.json)")
    with _export_to(out, materials[0], overwrite=overwrite) as tmp:
        manifest = write_site(materials, tmp, max_texels=max_texels)
    size = sum(e["page_bytes"] for e in manifest["materials"]) / 1e6
    console.print(escape(f"wrote {out} ({len(materials)} material(s), {size:.1f} MB of pages)"))
