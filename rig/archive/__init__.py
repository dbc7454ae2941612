"""The session archive: frames, step table, plan, rig config, calibration and
event log of one measurement session in a Zarr v3 directory, appended step by
step with crash-consistent commits (see ``docs/archive.md``).
"""

from rig.archive._errors import (
    ArchiveDamaged,
    ArchiveError,
    ArchiveFull,
    SessionFinished,
    StepAlreadyCommitted,
)
from rig.archive._index import FRAME_TABLE_DTYPE
from rig.archive._records import (
    FRAME_DTYPES,
    Event,
    FrameFlag,
    FrameFormat,
    FrameInfo,
    FrameRecord,
    StepRecord,
)
from rig.archive._repair import RepairReport, repair_archive
from rig.archive._store import overlaps_archive
from rig.archive._versions import software_versions
from rig.archive.archive import FORMAT_VERSION, Archive

__all__ = [
    "FORMAT_VERSION",
    "FRAME_DTYPES",
    "FRAME_TABLE_DTYPE",
    "Archive",
    "ArchiveDamaged",
    "ArchiveError",
    "ArchiveFull",
    "Event",
    "FrameFlag",
    "FrameFormat",
    "FrameInfo",
    "FrameRecord",
    "RepairReport",
    "SessionFinished",
    "StepAlreadyCommitted",
    "StepRecord",
    "overlaps_archive",
    "repair_archive",
    "software_versions",
]
