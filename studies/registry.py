"""Every study, by the name ``rig bench`` gives it.

A study is a module of this package with ``run(quick: bool) -> list[dict]`` (its
table's rows; ``quick``: the smaller sizes the tests use) and, where its rows have a
figure, ``plot(rows, path)``. The modules load when their study runs: between them
they import the GL renderer, the simulator and Dask, which ``rig --help`` does not need.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from types import ModuleType

__all__ = ["STUDIES", "Study", "study"]


@dataclass(frozen=True)
class Study:
    """One study: ``rig bench NAME`` runs ``studies.MODULE.run(quick)``.

    ``summary`` is the line ``rig bench --help`` lists; ``description`` what the
    study measures and what its table prints (``rig bench NAME --help``); ``figure``
    whether the module draws its rows (``plot(rows, path)``, ``--plot FILE``);
    ``selects`` which keyword arguments of ``run`` the command offers as options
    (``orchestrator.cli.bench_cmd.SELECTIONS``: ``scenes``, ``plans``,
    ``render_scale``, ``processings``, ``runs``), each checked against the module's
    ``SCENES``, ``PLANS``, ``PROCESSINGS`` or ``TERMS``.
    """

    name: str
    module: str
    summary: str
    description: str
    figure: bool = False
    selects: tuple[str, ...] = ()

    def load(self) -> ModuleType:
        """The study's module (imported on first use)."""
        return importlib.import_module(f"{__package__}.{self.module}")


STUDIES: tuple[Study, ...] = (
    Study(
        name="archive",
        module="archive_write",
        summary="Archive append speed against raw file writes",
        description=(
            "Append throughput of the session archive in raw frame MB/s, per method and frame "
            "content, against plain file writes in the same run and the seed rig's 141.6 MB/s "
            "of laser-scan frames; prints the median, min and max MB/s, the ratio to raw writes"
            " and the compression."
        ),
    ),
    Study(
        name="daemon",
        module="daemon_overhead",
        summary="The daemon's own cost per modelled session",
        description=(
            "The daemon's own cost: a session through the real daemon, sockets, archive and "
            "workers against a modelled rig in virtual time; prints per session size and worker"
            " count the wall time over the modelled hardware time (goal under 2 %) and "
            "frames/s."
        ),
    ),
    Study(
        name="process",
        module="process_scaling",
        summary="rig process speed-up against Dask workers",
        description=(
            "Items/s of `rig process --stages ps` on a simulated session against Dask workers "
            "(1, 2, all cores; threads and worker processes) and --size; prints the speed-up "
            "against one worker in the same run and where the time goes."
        ),
    ),
    Study(
        name="sim",
        module="sim_effects",
        summary="What each simulator effect costs per frame",
        description=(
            "What each simulator effect costs per frame: ms per new view and per re-lit view, "
            "for each effect alone and all together, per image size, as a ratio to plain "
            "Lambertian frames drawn in the same run."
        ),
    ),
    Study(
        name="ps",
        module="ps_cost",
        summary="Photometric-stereo accuracy against time",
        description=(
            "What photometric-stereo accuracy costs in time: seconds per megapixel of each "
            "solver and integrator beside the floor of one pass over the image stack, and the "
            "normal and height error against lamp count beside each set's capture time."
        ),
    ),
    Study(
        name="btf",
        module="btf_compression",
        summary="BTF error, time and size per component count",
        description=(
            "What each BTF compression level costs: per-view PCA and global SVD at each number "
            "of components c, their error on held-out images, compression time, size and peak "
            "memory, on a synthetic H2 BTF."
        ),
        figure=True,
    ),
    Study(
        name="mdf",
        module="mdf_cost",
        summary="MDF accuracy against capture and compute time",
        description=(
            "What MDF accuracy costs in capture and compute time: frames/s of the space-time "
            "peak detectors beside the floor of one pass over the frames, and the height error "
            "against scan locations and sweep step beside each scan's capture time."
        ),
    ),
    Study(
        name="calibration",
        module="calibration_error",
        summary="Calibration error against poses and heights",
        description=(
            "Calibration error against the simulator's truth and what it costs: reprojection, "
            "focal-length and camera-centre error against the number of turntable poses, laser-"
            "sheet angle error against target heights, beside each session's capture time."
        ),
    ),
    Study(
        name="radiometry",
        module="radiometry",
        summary="What response curves and flat fields buy",
        description=(
            "What the response curve and lamp flat fields buy in processing: photometric-stereo"
            " normal and albedo error and BTF error of a simulated sample with a gamma camera "
            "and near lamps, processed raw and corrected, against the same sample without those"
            " effects."
        ),
    ),
    Study(
        name="render",
        module="render_speed",
        summary="Renderer frames/s against components and slots",
        description=(
            "Frames/s of the GL renderer at 800 × 600 against the number of components and "
            "blended view slots, as a ratio to a plain textured quad drawn in the same run, and"
            " the MDF's depth-peeling passes against the BTF alone."
        ),
    ),
    Study(
        name="render-loop",
        module="render_loop",
        summary="Rendered PSNR at unmeasured directions per plan",
        description=(
            "The renderer against the simulator: simulated samples measured on plans from "
            "coarse to H1, processed and rendered at directions no plan captured; prints PSNR "
            "against the noise-free truth beside each plan's capture time."
        ),
        figure=True,
        selects=("scenes", "plans"),
    ),
    Study(
        name="error-budget",
        module="error_budget",
        summary="Render-loop PSNR with each error term off",
        description=(
            "The render loop's PSNR at captured and held-out directions with the simulator's "
            "noise, near lamps, point-sampled pixels and perspective, and registration's "
            "markers and box filter, switched off one at a time and together, each session "
            "processed raw and corrected, at c = 4 and lossless, beside the floor the sensor "
            "model's noise sets at the captured pairs (coarse and medium plans; --quick: the "
            "coarse plan at 32² texels)."
        ),
        figure=True,
        selects=("scenes", "plans", "render_scale", "processings", "runs"),
    ),
    Study(
        name="lab-loop",
        module="lab_loop",
        summary="Render loop on a rig not built to its config",
        description=(
            "The render loop as a lab runs it: a simulated rig whose lamps stand ±5 mm and "
            "±5 % off its config, its lamps calibrated by the mirror-sphere and white-target "
            "sessions, the coarse and medium BTF plans measured on it and processed with the "
            "nominal config, with the calibration applied (and each texel's light moved by the "
            "fitted PBR model), and on a rig built exactly to its config; PSNR at captured "
            "and held-out pairs, and the calibrated lamps' errors "
            "(--quick: the bumps at 32² texels on the coarse plan)."
        ),
        selects=("scenes", "plans"),
    ),
    Study(
        name="silhouettes",
        module="silhouettes",
        summary="MDF silhouettes against the ray-cast truth",
        description=(
            "MDF silhouettes against the ray-cast truth: intersection over union and the width "
            "of the outline's error band in pixels, per sample, mesh and number of depth-"
            "peeling passes, with the MDF and without it."
        ),
    ),
    Study(
        name="mdf-shadows",
        module="mdf_shadows",
        summary="Shadow boundaries on the MDF against the truth",
        description=(
            "Shadow boundaries on a BTF + MDF plane against the ray-cast truth: the fraction of"
            " the plane's pixels whose lit or shadowed state agrees with the truth, over the "
            "whole plane and near the true boundary, without the MDF and with it (--quick: 128²"
            " instead of 256² pixels)."
        ),
    ),
    Study(
        name="environment",
        module="environment",
        summary="Environment lighting's error against its time",
        description=(
            "What environment lighting's accuracy costs in time: error of the visibility maps, "
            "their PCA of rotations and the partial environment maps against a brute-force sum,"
            " beside the time per frame as a ratio to a point-light frame."
        ),
    ),
    Study(
        name="ps-kinds",
        module="ps_kinds",
        summary="Normal error of photometric stereo per rig kind",
        description=(
            "Photometric stereo on each rig kind against the simulator's ray-cast truth: "
            "sessions of the VirTex stage (3 and 6 lamps) and the Wang rig (12 lamps) through "
            "the daemon and the real drivers, processed with the robust solver; prints the "
            "mean and 95th-percentile normal error, the valid fraction and each session's "
            "rig time, without effects and with shadows and noise."
        ),
    ),
    Study(
        name="mdf-sim",
        module="mdf_sim",
        summary="MDF height error against laser locations",
        description=(
            "MDF accuracy end to end against the simulator's ray-cast truth: scan sessions "
            "with 1, 5, 13 and 26 laser locations through the daemon and the real drivers, "
            "processed on 128² texels; prints the median and 95th-percentile height error, "
            "the coverage and each session's rig time, per example scene."
        ),
    ),
    Study(
        name="registration-sim",
        module="registration_sim",
        summary="Registration of every H1 view against the truth",
        description=(
            "Registration of simulated frames at every H1 view up to θ = 75° against the "
            "simulator's truth: markers found, reprojection and corner error against the true "
            "projection, texture RMSE of clean and noisy frames against the ray-cast BTF, "
            "anti-aliased and point-sampled (--quick: six views)."
        ),
        figure=True,
    ),
    Study(
        name="bonn-registration",
        module="bonn_registration",
        summary="Registration on the simulated Bonn lab",
        description=(
            "Registration on the simulated Bonn lab against the simulator's truth: for six "
            "(view, light) pairs the real drivers pose the arm and the rail, the frame is "
            "registered and compared with the ray-cast BTF; prints markers, reprojection, "
            "corner error against the lab's camera model and texture RMSE per pair."
        ),
    ),
    Study(
        name="bonn-h1",
        module="bonn_h1",
        summary="A full H1 session on the simulated Bonn lab",
        description=(
            "A full H1 BTF session on the simulated Bonn lab through the daemon and the real "
            "drivers, every pair captured once and every frame registered (from the markers, "
            "else from the arm's pose) and compared with the simulator's truth; prints per "
            "view ring the steps, the registrations by source, the marker reprojection and "
            "the texture RMSE (hours; --quick: the first view's 81 pairs)."
        ),
    ),
    Study(
        name="live-memory",
        module="live_memory",
        summary="Peak memory of a session against its length",
        description=(
            "Peak memory of a session with a live register worker against its length: "
            "daemon, worker and a modelled rig in one process on virtual time; prints per "
            "session of 200 to 2,000 frames the frames processed, the peak of Python "
            "allocations (MB) and the wall time (--quick: 200 and 1000 frames)."
        ),
    ),
)


def study(name: str) -> Study:
    """The study ``rig bench NAME`` runs; a ``KeyError`` names the valid ones."""
    for entry in STUDIES:
        if entry.name == name:
            return entry
    raise KeyError(f"no study {name!r}: valid are {', '.join(s.name for s in STUDIES)}")
