"""Frame flags (archive format 2): stored with the step, rebuilt by repair, and a
format-1 archive, written before they existed, still opens with none."""

import json

import numpy as np
import pytest

from rig.archive import Archive, ArchiveError, FrameFlag, FrameFormat, StepRecord, repair_archive
from rig.archive._journal import encode_event

CAMERAS = {"cam0": FrameFormat(8, 12, 1, "uint8"), "cam1": FrameFormat(8, 12, 1, "uint8")}
TILT = "laser tilt read back 6.000°…6.000° around the exposure, planned 1.333° ± 0.133°"


def _scan_step(index: int, flags=()) -> StepRecord:
    return StepRecord(
        index=index, kind="mdf", cameras=tuple(CAMERAS), exposures_s=(0.005,), laser=0,
        flags=flags,
    )  # fmt: skip


def _frames(n: int) -> dict:
    return {c: [np.full(f.shape, i, dtype=f.dtype) for i in range(n)] for c, f in CAMERAS.items()}


@pytest.fixture
def flagged(tmp_path):
    path = tmp_path / "s.zarr"
    flags = (FrameFlag("cam0", 2, TILT, recaptured=True), FrameFlag("cam1", 3, TILT, False))
    with Archive.create(path, plan={}, rig_config={}, cameras=CAMERAS) as archive:
        archive.append_step(_scan_step(0), _frames(4))
        archive.append_step(_scan_step(1, flags), _frames(4))
    return path, flags


def test_flags_come_back_with_their_step_and_say_what_processing_leaves_out(flagged):
    path, flags = flagged
    with Archive.open(path, mode="r") as archive:
        steps = archive.step_table()
    assert steps[0].flags == () and steps[1].flags == flags
    assert steps[1].excluded("cam0") == frozenset()  # taken again: it counts
    assert steps[1].excluded("cam1") == frozenset({3})


def test_repair_rebuilds_the_flags_from_the_chunks_own_records(flagged):
    path, flags = flagged
    (path / "log" / "journal.jsonl").unlink()
    repair_archive(path, fsync=False)
    with Archive.open(path, mode="r") as archive:
        assert archive.step_table()[1].flags == flags


def test_a_format_1_archive_opens_with_no_flags(tmp_path):
    path = tmp_path / "old.zarr"
    with Archive.create(path, plan={}, rig_config={}, cameras=CAMERAS) as archive:
        archive.append_step(_scan_step(0), _frames(2))
    # what format 1 wrote: its marker, and step records without the flags field
    root = path / "zarr.json"
    document = json.loads(root.read_text())
    document["attributes"]["btfrig_archive"]["format_version"] = 1
    root.write_text(json.dumps(document))
    journal = path / "log" / "journal.jsonl"
    lines = [json.loads(line) for line in journal.read_text().splitlines()]
    for line in lines:
        line["payload"].get("step", {}).pop("flags", None)
    journal.write_bytes(
        b"".join(encode_event(e["seq"], e["time"], e["kind"], e["payload"]) for e in lines)
    )
    assert b"flags" not in journal.read_bytes()
    with Archive.open(path, mode="r") as archive:
        assert [s.flags for s in archive.step_table()] == [()]


@pytest.mark.parametrize(
    ("flag", "message"),
    [
        (dict(camera="", sub=0, reason="x", recaptured=True), "must be a camera name"),
        (dict(camera="cam0", sub=-1, reason="x", recaptured=True), r"must be an int ≥ 0"),
        (dict(camera="cam0", sub=0, reason="", recaptured=True), "must say why"),
    ],
)
def test_a_bad_flag_is_refused_naming_the_field(flag, message):
    with pytest.raises(ArchiveError, match=message):
        FrameFlag(**flag)


def test_a_flag_of_a_camera_the_step_does_not_have_is_refused():
    with pytest.raises(ArchiveError, match=r"step 0: flags holds .*'cam9'"):
        _scan_step(0, (FrameFlag("cam9", 0, TILT, True),))
