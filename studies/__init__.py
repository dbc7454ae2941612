"""btfrig's studies: benches and the measurements behind the docs' tables and figures.

Each study measures the rig, the processing or the renderer against a known truth or a
baseline drawn in the same run, and returns rows: ``run(quick) -> list[dict]``, plus
``plot(rows, path)`` where its rows have a figure. :data:`STUDIES` lists them by the
name ``rig bench`` gives them. The studies sit above the orchestrator (some run whole
sessions through it) and below its command line; nothing below imports them.
"""

from pathlib import Path

from studies.registry import STUDIES, Study, study

__all__ = ["EXAMPLE_SCENES", "STUDIES", "Study", "study"]

#: The example scenes the studies simulate (``examples/scenes`` of the repository).
EXAMPLE_SCENES = Path(__file__).resolve().parents[1] / "examples" / "scenes"
