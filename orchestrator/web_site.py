"""A self-contained static site of measured materials (``rig export web``).

Each material gets a page that draws its BTF (per-view PCA, the renderer's nearest-four
Shepard blends of view slots and lights) or its glTF PBR fit on the built-in meshes in
plain WebGL2 (``orchestrator/web/viewer.js``, no third-party code); the index lists them
with a thumbnail the project's renderer made, the sample's name and size, its sampling,
capture date and fit error. Data ride in ``data.js`` files (base64 arrays), so the site
works from ``file://`` as from any static server and fetches nothing from outside.

Texture budget: the BTF's texel grid is area-averaged down to ``max_texels`` per side
and each view slot keeps its PCA components; the bytes of every page are in
``manifest.json`` and on the index.
"""

from __future__ import annotations

import base64
import datetime
import html
import json
import shutil
from pathlib import Path

import numpy as np

from orchestrator.cli.view_scene import auto_exposure_ev, parse_camera, parse_light
from processing.offline.btf import resample_texels
from rig.errors import ConfigError
from rig.geometry import LIGHT_COSINE_FLOOR
from rig.material import CompressedBTF, Material, pbr_layers, read_material, sheen_albedo

__all__ = ["CAMERA", "CANVAS", "LIGHT", "MESHES", "write_site"]

#: the viewer's canvas and its starting camera and light (``rig view``'s defaults)
CANVAS = (640, 480)
CAMERA = "orbit:60,-90"
LIGHT = "dir:40,-130"
FOV_DEG = 30.0
MESHES = ("plane", "sphere", "cylinder", "torus", "cloth")
_WEB = Path(__file__).with_name("web")


def _b64(array: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(array).tobytes()).decode("ascii")


def _meshes() -> dict:
    from render.meshes import mesh_by_name

    out = {}
    for name in MESHES:
        mesh = mesh_by_name(name)
        positions = np.asarray(mesh.positions, np.float32)
        out[name] = {
            "position": _b64(positions), "normal": _b64(np.asarray(mesh.normals, np.float32)),
            "tangent": _b64(np.asarray(mesh.tangents, np.float32)),
            "uv": _b64(np.asarray(mesh.uvs, np.float32)),
            "faces": _b64(np.asarray(mesh.faces, np.uint32)),
            "radius": float(np.linalg.norm(np.ptp(positions, axis=0)) / 2),
        }  # fmt: skip
    return out


def _cameras() -> dict:
    from render.meshes import mesh_by_name

    spec = parse_camera(CAMERA)
    cameras = {}
    for name in MESHES:
        camera = spec.camera(mesh_by_name(name), CANVAS, FOV_DEG)
        cameras[name] = {
            "eye": camera.eye.tolist(), "target": camera.target.tolist(), "fov": FOV_DEG
        }  # fmt: skip
    return cameras


def _grid(stack: np.ndarray, size: int) -> np.ndarray:
    """(..., N, N, C) on the size² grid, rows flipped as GL uploads them (t = 0 at −y)."""
    flat = stack.reshape(-1, *stack.shape[-3:]).astype(np.float32)
    resized = np.stack([resample_texels(image, size) for image in flat])
    return resized[:, ::-1].reshape(*stack.shape[:-3], size, size, stack.shape[-1])


def _material_data(material: Material, *, max_texels: int) -> dict:
    """What ``viewer.js`` reads of one material (the ``window.BTFRIG`` object)."""
    btf, fit = material.btf, material.pbr
    size = min(btf.size, max_texels)
    c = btf.components
    images = np.concatenate([np.asarray(btf.basis), np.asarray(btf.mean)[:, None]], axis=1)
    if images.shape[-1] == 1:
        images = np.repeat(images, 3, axis=-1)
    images = _grid(images, size).astype(np.float16)  # (V, c + 1, n, n, 3)
    padded = np.zeros((*btf.weights.shape[:2], 4 * -(-c // 4)), np.float32)
    padded[..., :c] = btf.weights
    layers = pbr_layers(fit)
    cos = np.linspace(0.0, 1.0, 33)
    rough = np.linspace(0.07, 1.0, 25)
    lut = sheen_albedo(cos[:, None], rough[None, :]).astype(np.float32)  # rows: cos
    valid = material.btf_slot_valid
    return {
        "size": size, "components": c, "sample_mm": material.sample_mm,
        "views": btf.view_vectors.tolist(), "lights": btf.light_vectors.tolist(),
        "light_cosine_floor": LIGHT_COSINE_FLOOR,
        "slot_valid": [1.0 if v else 0.0 for v in (np.ones(len(btf.view_dirs_deg), bool)
                                                    if valid is None else valid)],
        "btf": _b64(images), "weights": _b64(padded),
        "pbr": _b64(_grid(layers, size).astype(np.float16)),
        "white": float(fit.attrs.get("white", 1.0)),
        "sheen_lut": {"values": _b64(lut), "cos": len(cos), "roughness": len(rough)},
    }  # fmt: skip


def _thumbnail(material: Material, path: Path, size=(320, 240)) -> float:
    """The material on the cloth, rendered by ``render``; the exposure (EV) it used."""
    from render import Renderer
    from render.meshes import cloth
    from render.output import write_png

    mesh = cloth()
    camera = parse_camera(CAMERA).camera(mesh, size, FOV_DEG)
    light = parse_light(LIGHT).light(np.zeros(3))
    with Renderer(material, mesh, mdf=False) as renderer:
        image = renderer.render(camera, [light])
    exposure = auto_exposure_ev(image)
    write_png(path, image, exposure_ev=exposure)
    return exposure


def _captured(path: Path) -> str:
    """The date of the archive's first event (UTC), or "unknown" for a material store."""
    from rig.archive import Archive, ArchiveError

    try:
        with Archive.open(path, mode="r") as archive:
            times = [e.time for e in archive.events()]
    except ArchiveError:  # a material store is not an archive: no date to show
        return "unknown"
    if not times:
        return "unknown"
    return datetime.datetime.fromtimestamp(min(times), datetime.UTC).strftime("%Y-%m-%d")


def write_site(sources: list[Path], out: Path, *, max_texels: int = 256) -> dict:
    """Write the site for the materials at ``sources`` into the empty folder ``out``.

    Returns the manifest (also written as ``out/manifest.json``). ConfigError when a
    material has no BTF (per-view PCA) or no PBR fit.
    """
    from render import shader_source

    shutil.copy(_WEB / "viewer.js", out / "viewer.js")
    pbr_glsl = json.dumps(shader_source("pbr.glsl"))
    (out / "shaders.js").write_text(f"window.BTFRIG_PBR_GLSL = {pbr_glsl};\n")
    (out / "meshes.js").write_text("window.BTFRIG_MESHES = " + json.dumps(_meshes()) + ";\n")
    cameras = _cameras()
    entries, taken = [], set()
    for source in sources:
        material = read_material(source)
        if not isinstance(material.btf, CompressedBTF) or material.pbr is None:
            raise ConfigError(
                f"{source}: the web viewer needs a per-view PCA BTF and its PBR fit; run "
                "`rig process --stages btf,pbr` first"
            )
        name = source.name.removesuffix(".zarr") or "material"
        while name in taken:
            name += "_"
        taken.add(name)
        folder = out / name
        folder.mkdir()
        data = _material_data(material, max_texels=max_texels)
        exposure = _thumbnail(material, folder / "thumbnail.png")
        theta_phi = parse_light(LIGHT).where
        data.update(name=name, mesh="plane", cameras=cameras, exposure_ev=exposure,
                    light_deg=list(theta_phi))  # fmt: skip
        (folder / "data.js").write_text("window.BTFRIG = " + json.dumps(data) + ";\n")
        (folder / "index.html").write_text(_page(name))
        entries.append(_entry(name, source, material, folder, data))
    (out / "index.html").write_text(_index(entries))
    manifest = {
        "materials": entries, "canvas": list(CANVAS), "camera": CAMERA, "light": LIGHT,
        "max_texels": max_texels, "third_party_code": "none (plain WebGL2)",
    }  # fmt: skip
    (out / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    return manifest


def _entry(name: str, source: Path, material: Material, folder: Path, data: dict) -> dict:
    btf, fit = material.btf, material.pbr
    return {
        "name": name, "page": f"{name}/index.html", "source": str(source.resolve()),
        "sample_mm": material.sample_mm, "texels": data["size"],
        "views": len(btf.view_dirs_deg), "lights": len(btf.light_dirs_deg),
        "components": btf.components, "captured": _captured(source),
        "fit_psnr_db": fit.attrs.get("psnr_db"), "fit_rmse": fit.attrs.get("rmse"),
        "page_bytes": sum(f.stat().st_size for f in folder.iterdir()),
    }  # fmt: skip


def _page(name: str) -> str:
    title = html.escape(name)
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{title} — btfrig</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<link rel="icon" href="data:,">
<style>body{{font:14px sans-serif;margin:1em;background:#222;color:#eee}}
canvas{{max-width:100%;height:auto;touch-action:none;background:#000}}
a{{color:#9cf}} .bar>*{{margin-right:1em}}</style></head>
<body><p><a href="../index.html">catalogue</a> · <b>{title}</b></p>
<canvas id="view" width="{CANVAS[0]}" height="{CANVAS[1]}"></canvas>
<p class="bar"><label>mesh <select id="mesh"></select></label>
<button id="mode">measured BTF</button>
<label>exposure <input id="exposure" type="range" min="-12" max="12" step="0.1"></label>
<span id="status">loading…</span></p>
<p>Drag to orbit; shift-drag to move the light.</p>
<script src="data.js"></script><script src="../meshes.js"></script>
<script src="../shaders.js"></script>
<script src="../viewer.js"></script></body></html>
"""


def _index(entries: list[dict]) -> str:
    rows = []
    for e in entries:
        name = html.escape(e["name"])
        link = f'<a href="{e["page"]}">'
        rows.append(
            f'<tr><td>{link}<img src="{name}/thumbnail.png" width="160" alt="{name}"></a></td>'
            f'<td>{link}{name}</a></td><td>{e["sample_mm"]:g} mm, '
            f'{e["texels"]}² texels</td><td>{e["views"]} views × {e["lights"]} lights, '
            f'{e["components"]} components</td><td>{html.escape(e["captured"])}</td>'
            f'<td>{e["fit_psnr_db"]:.1f} dB</td><td>{e["page_bytes"] / 1e6:.1f} MB</td></tr>'
        )
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>btfrig materials</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<link rel="icon" href="data:,">
<style>body{{font:14px sans-serif;margin:1em}} td{{padding:4px 8px}}</style></head>
<body><h1>Measured materials</h1>
<table><tr><th></th><th>sample</th><th>size</th><th>sampling</th><th>captured</th>
<th>PBR fit error</th><th>page</th></tr>
{chr(10).join(rows)}
</table>
<p>Fit error: PSNR of the PBR fit against the BTF at its measured pairs. Each page
loads its BTF (float16, at most the stated texels per side) in one script.</p>
</body></html>
"""
