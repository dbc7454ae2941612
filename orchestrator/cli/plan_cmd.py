"""`rig plan`: validate a plan, compile it for a rig, estimate time and data."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from orchestrator.cli.common import console, load_config_option, working
from rig.config import RigConfig
from rig.kinematics import sampling_residuals
from rig.plan import Plan, load_plan
from rig.schedule import compile_plan
from rig.steps import Schedule

__all__ = ["register"]


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


def register(app: typer.Typer) -> None:
    @app.command()
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
    ) -> None:
        """Validate a plan; with --estimate, compile it for the rig and say what it costs."""
        the_plan = load_plan(plan_file)
        rig = load_config_option(config)
        console.print(
            f"plan [bold]{escape(str(plan_file))}[/bold] is valid "
            f"(sample {escape(the_plan.sample.name)})"
        )
        if residuals:
            _print_residuals(the_plan, rig)
        if not (estimate or steps):
            return
        with working(f"compiling the plan for the {rig.kind} rig {rig.name}"):
            schedule = compile_plan(the_plan, rig)
        if estimate:
            print_estimate(schedule)
        if steps:
            _print_steps(schedule, steps)


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
