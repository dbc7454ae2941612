"""`rig plan`: validate a plan, compile it for a rig, estimate time and data, predict accuracy."""

from __future__ import annotations

from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from orchestrator.cli.common import console, load_config_option, quiet_dask_logs, working
from rig.config import RigConfig
from rig.errors import PlanError
from rig.kinematics import sampling_residuals
from rig.plan import Plan, load_plan
from rig.schedule import compile_plan
from rig.steps import Schedule

__all__ = ["PredictOptions", "plan", "print_estimate", "register"]


def _hms(seconds: float) -> str:
    s = round(seconds)
    return f"{s // 3600:d}:{s % 3600 // 60:02d}:{s % 60:02d}"


def _size(n_bytes: int) -> str:
    for unit in ("B", "KB", "MB", "GB", "TB"):
        if n_bytes < 1000 or unit == "TB":
            return f"{n_bytes:.1f} {unit}" if unit != "B" else f"{n_bytes} B"
        n_bytes /= 1000
    raise AssertionError("unreachable")


def print_estimate(schedule: Schedule) -> None:
    est, naive = schedule.estimate, schedule.naive_estimate
    table = Table(title="Session estimate", show_header=False)
    table.add_row("direction pairs", str(schedule.pairs))
    table.add_row("steps", str(len(schedule.steps)))
    for kind, seconds in sorted(est.by_kind_s.items()):
        table.add_row(f"  {kind}", _hms(seconds))
    table.add_row("motion + settle", _hms(est.motion_s))
    table.add_row("lamp warm-up", _hms(est.lamp_s))
    table.add_row("exposure + readout", _hms(est.capture_s))
    table.add_row("[bold]expected duration[/bold]", f"[bold]{_hms(est.total_s)}[/bold]")
    saving = naive.total_s - est.total_s
    pct = 100 * saving / naive.total_s if naive.total_s > 0 else 0.0
    table.add_row(
        "motion order saves",
        f"{_hms(saving)} ({pct:.0f} %) against the plan's own order ({_hms(naive.total_s)})",
    )
    table.add_row("frames", str(est.frames))
    table.add_row("[bold]data size[/bold]", f"[bold]{_size(est.bytes)}[/bold]")
    table.add_row("largest view residual", f"{schedule.max_view_residual_deg:.2f}°")
    table.add_row("largest light residual", f"{schedule.max_light_residual_deg:.2f}°")
    console.print(table)


@dataclass(frozen=True)
class PredictOptions:
    """What `rig plan --predict` runs: the proxy ``sample`` (``bumps``, ``weave`` or a
    scene file) and the plans to set beside the first (``compare``)."""

    sample: str
    compare: tuple[Path, ...]


def plan(
    plan_file: Annotated[Path, typer.Argument(help="the plan TOML")],
    config: Annotated[
        Path | None, typer.Option("--config", "-c", help="rig config TOML (default rig)")
    ] = None,
    estimate: Annotated[
        bool, typer.Option("--estimate", help="compile and print duration and data size")
    ] = False,
    steps: Annotated[
        int, typer.Option("--steps", min=0, help="also list the first N compiled steps")
    ] = 0,
    residuals: Annotated[
        bool,
        typer.Option("--residuals", help="how closely the rig hits each sampling, per ring"),
    ] = False,
    predict: Annotated[
        bool,
        typer.Option(
            "--predict",
            help="run the plan's BTF capture on the simulated rig with a proxy sample "
            "(virtual time, cameras at 1/4 of their size, 32² texels, only the view slots "
            "the scores read: minutes, not hours), process it and print the predicted PSNR "
            "per component count c at the captured pairs nearest four held-out directions "
            "and at those directions, beside the whole plan's duration and data size",
        ),
    ] = False,
    sample: Annotated[
        str,
        typer.Option(
            "--sample",
            help="--predict: the proxy sample, bumps | weave | a scene TOML file",
        ),
    ] = "bumps",
    compare: Annotated[
        list[Path] | None,
        typer.Option(
            "--compare",
            metavar="PLAN2",
            help="--predict this plan too, one table for all; repeatable (implies --predict)",
        ),
    ] = None,
) -> None:
    """Validate a plan, estimate its cost, predict its accuracy.

    With --estimate, compile it for the rig and say what it costs (duration, data
    size); with --predict, what accuracy it buys on a simulated sample."""
    the_plan = load_plan(plan_file)
    rig = load_config_option(config)
    console.print(
        f"plan [bold]{escape(str(plan_file))}[/bold] is valid "
        f"(sample {escape(the_plan.sample.name)})"
    )
    if residuals:
        _print_residuals(the_plan, rig)
    if estimate or steps:
        with working(f"compiling the plan for the {rig.kind} rig {rig.name}"):
            schedule = compile_plan(the_plan, rig)
        if estimate:
            print_estimate(schedule)
        if steps:
            _print_steps(schedule, steps)
    if predict or compare:
        print_predictions(plan_file, rig, PredictOptions(sample, tuple(compare or ())))


def register(app: typer.Typer) -> None:
    """Add `rig plan` to ``app``."""
    app.command()(plan)


def _print_steps(schedule: Schedule, n: int) -> None:
    table = Table(title=f"First {min(n, len(schedule.steps))} of {len(schedule.steps)} steps")
    for col in ("#", "kind", "pose", "source", "cameras", "frames/cam"):
        table.add_column(col)
    for step in schedule.steps[:n]:
        table.add_row(
            str(step.index),
            step.kind,
            step.pose.summary(),
            step.source,
            ",".join(step.cameras),
            str(step.frames_per_camera),
        )
    console.print(table)


def _print_residuals(the_plan: Plan, rig: RigConfig) -> None:
    seen = set()
    for kind in ("btf", "ps", "mdf"):
        capture = getattr(the_plan.captures, kind)
        if capture is None:
            continue
        for field in type(capture).model_fields:
            spec = getattr(capture, field)
            if not hasattr(spec, "resolve"):
                continue
            sampling = spec.resolve()
            key = (sampling.name, sampling.directions.tobytes())
            if key in seen:
                continue
            seen.add(key)
            table = Table(title=f"{kind}.{field}: sampling {sampling.name} on rig {rig.name}")
            for col in ("θ ring", "directions", "max view residual", "max light residual"):
                table.add_column(col)
            for row in sampling_residuals(rig, sampling):
                table.add_row(
                    f"{row['theta_deg']:g}°",
                    str(row["count"]),
                    f"{row['max_view_residual_deg']:.2f}°",
                    f"{row['max_light_residual_deg']:.2f}°",
                )
            console.print(table)


def print_predictions(plan_file: Path, rig: RigConfig, options: PredictOptions) -> None:
    """Predict each plan's accuracy (``studies.plan_predict``) and print one table:
    per plan and c, the duration and data size on ``rig`` and the PSNR at the
    captured pairs and the held-out directions."""
    from studies.plan_predict import SENSOR_SCALE, TEXELS, predict, proxy_scene

    quiet_dask_logs()  # the btf stage runs on a local Dask cluster
    scene = proxy_scene(options.sample)  # a bad --sample before any work
    plans = {path: load_plan(path) for path in (plan_file, *options.compare)}
    for path, the_plan in plans.items():
        if the_plan.captures.btf is None:
            raise PlanError(str(path), ["captures.btf: --predict scores a BTF; the plan has none"])
    table = Table(
        title=f"Predicted accuracy on the simulated {options.sample} "
        f"(cameras at 1/{round(1 / SENSOR_SCALE)} size, {TEXELS}² texels)"
    )
    columns = ("plan", "frames", "duration", "data size", "views registered",
               "gap view / light", "c", "captured dB", "held-out dB")  # fmt: skip
    for col in columns:
        table.add_column(col, justify="left" if col == "plan" else "right")
    for path, the_plan in plans.items():
        estimate = compile_plan(the_plan, rig).estimate
        with _Progress(path.name) as progress:
            found = predict(the_plan, scene, on_session=progress.session,
                            on_event=progress.event, on_stage=progress.stage)  # fmt: skip
        views = f"{found.views}/{found.recorded}"
        if found.recorded < found.view_slots:
            views += f" of {found.view_slots}"
        for c, held_out_db in found.held_out_db.items():
            table.add_row(escape(str(path)), str(estimate.frames), _hms(estimate.total_s),
                          _size(estimate.bytes), views,
                          f"{found.view_gap_deg:.0f}° / {found.light_gap_deg:.0f}°", str(c),
                          f"{found.captured_db[c]:.1f}", f"{held_out_db:.1f}")  # fmt: skip
        table.add_section()
    table.caption = (
        "PSNR against the simulator's noise-free truth; captured: the material at the "
        "captured pairs nearest four held-out directions; held-out: interpolated at those "
        "directions, the gap from the nearest captured view / light; views registered: of "
        "the view slots these scores read, which alone are simulated (of the plan's)"
    )
    console.print(table)


class _Progress:
    """On stderr: a bar over the session's steps, then a spinner per stage."""

    def __init__(self, name: str) -> None:
        self.name, self.steps, self.done = name, 0, 0
        self.stack = ExitStack()

    def __enter__(self) -> _Progress:
        return self

    def session(self, steps: int) -> None:
        self.stack.close()
        self.steps, self.done = steps, 0
        self.advance = self.stack.enter_context(
            working(f"{self.name}: the session on the simulated rig", total=steps)
        )

    def __exit__(self, *exc) -> None:
        self.stack.close()

    def event(self, event: dict) -> None:
        if event.get("topic") == "progress":
            while self.done < min(int(event.get("step", 0)), self.steps):
                self.advance()
                self.done += 1

    def stage(self, what: str) -> None:
        self.stack.close()
        self.stack.enter_context(working(f"{self.name}: {what}"))
