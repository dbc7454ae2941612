"""Offline processing of recorded sessions (``rig process``): stages run on Dask.

``run_stages(archive, [STAGES["ps"]])`` splits each stage into independent
items, computes them on a Dask cluster (local by default) and writes each
stage's results atomically into the archive's ``material/<stage>`` group.
See ``docs/processing.md`` for the stage protocol.
"""

from processing.offline.btf import BtfSlot, BtfStage
from processing.offline.mdf import MdfStage, MdfView
from processing.offline.ps import PsStage, PsView
from processing.offline.runner import Stage, StageRun, run_stages

#: stage name → how to build it (keyword options, e.g. ``size=``)
STAGES = {"ps": PsStage, "btf": BtfStage, "mdf": MdfStage}

__all__ = [
    "STAGES",
    "BtfSlot",
    "BtfStage",
    "MdfStage",
    "MdfView",
    "PsStage",
    "PsView",
    "Stage",
    "StageRun",
    "run_stages",
]
