"""Offline processing of recorded sessions (``rig process``): stages run on Dask.

``run_stages(archive, [STAGES["ps"]])`` splits each stage into independent
items, computes them on a Dask cluster (local by default) and writes each
stage's results atomically into the archive's ``material/<stage>`` group.
See ``docs/processing.md`` for the stage protocol.
"""

from processing.offline.btf import BtfSlot, BtfStage
from processing.offline.mdf import MdfStage
from processing.offline.pbr import PbrStage
from processing.offline.ps import PsStage
from processing.offline.runner import (
    Stage,
    StageFailed,
    StageRun,
    StageSkipped,
    View,
    frame_camera,
    run_stages,
    views_of,
)

#: stage name → how to build it (keyword options, e.g. ``size=``)
STAGES = {"ps": PsStage, "btf": BtfStage, "mdf": MdfStage, "pbr": PbrStage}

__all__ = [
    "STAGES",
    "BtfSlot",
    "BtfStage",
    "MdfStage",
    "PbrStage",
    "PsStage",
    "Stage",
    "StageFailed",
    "StageRun",
    "StageSkipped",
    "View",
    "frame_camera",
    "run_stages",
    "views_of",
]
