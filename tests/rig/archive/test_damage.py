"""A damaged archive raises ArchiveError saying what is wrong and where."""

import json
import re
import shutil

import numpy as np
import pytest

from rig.archive import Archive, ArchiveError, FrameFormat, StepRecord
from rig.errors import RigError

CAMERAS = {"rgb": FrameFormat(16, 24, 3, "uint8"), "depth": FrameFormat(8, 8, 1, "float32")}


def _frame(fmt: FrameFormat, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (rng.random(fmt.shape) * 200).astype(fmt.dtype)


@pytest.fixture
def archive_path(tmp_path):
    path = tmp_path / "s.zarr"
    with Archive.create(path, plan={}, rig_config={}, cameras=CAMERAS) as archive:
        for index in range(3):
            frames = {c: [_frame(f, 10 * index + s) for s in range(2)] for c, f in CAMERAS.items()}
            archive.append_step(
                StepRecord(index=index, kind="ps", cameras=tuple(CAMERAS), exposures_s=(0.01,)),
                frames,
            )
    return path


def _open_fails(path, message: str) -> ArchiveError:
    with pytest.raises(ArchiveError, match=message) as err:
        Archive.open(path).close()
    assert isinstance(err.value, RigError)
    return err.value


def _edit_json(path, edit) -> None:
    document = json.loads(path.read_text())
    edit(document)
    path.write_text(json.dumps(document))


def test_not_an_archive(tmp_path):
    _open_fails(tmp_path / "nothing.zarr", "no archive here")
    (tmp_path / "empty.zarr").mkdir()
    _open_fails(tmp_path / "empty.zarr", r"empty\.zarr: missing group metadata zarr\.json")


def test_missing_group(archive_path):
    shutil.rmtree(archive_path / "material")
    _open_fails(archive_path, r"s\.zarr/material: missing group metadata zarr\.json")


def test_missing_frames_group(archive_path):
    shutil.rmtree(archive_path / "frames")
    _open_fails(archive_path, r"s\.zarr/frames: missing group metadata")


def test_missing_camera_array(archive_path):
    (archive_path / "frames" / "depth" / "zarr.json").unlink()
    _open_fails(archive_path, r"frames/depth: missing array metadata zarr\.json")


def test_missing_root_attribute(archive_path):
    _edit_json(archive_path / "zarr.json", lambda d: d["attributes"].pop("cameras"))
    _open_fails(archive_path, r"zarr\.json: attribute 'cameras' is missing")


def test_unreadable_metadata(archive_path):
    (archive_path / "frames" / "rgb" / "zarr.json").write_text('{"zarr_format": 3, "node')
    _open_fails(archive_path, r"frames/rgb/zarr\.json: unreadable metadata")


def test_wrong_dtype(archive_path):
    _edit_json(
        archive_path / "frames" / "rgb" / "zarr.json", lambda d: d.update(data_type="uint16")
    )
    _open_fails(archive_path, r"frames/rgb/zarr\.json: dtype 'uint16', but .* declares 'uint8'")


def test_wrong_frame_shape(archive_path):
    def edit(document):
        document["shape"][2] = 25

    _edit_json(archive_path / "frames" / "rgb" / "zarr.json", edit)
    _open_fails(
        archive_path, r"frames/rgb/zarr\.json: shape \[6, 16, 25, 3\], expected \[n, 16, 24, 3\]"
    )


def test_wrong_codec(archive_path):
    _edit_json(
        archive_path / "frames" / "depth" / "zarr.json",
        lambda d: d.update(codecs=[{"name": "bytes"}, {"name": "gzip"}]),
    )
    _open_fails(archive_path, r"codecs \['bytes', 'gzip'\], expected \['bytes', 'zstd'\]")


def test_newer_format_version(archive_path):
    _edit_json(
        archive_path / "zarr.json",
        lambda d: d["attributes"]["btfrig_archive"].update(format_version=99),
    )
    _open_fails(archive_path, r"archive format version 99, this btfrig reads versions \[1, 2\]")


def test_truncated_chunk(archive_path):
    chunk = archive_path / "frames" / "rgb" / "c.3.0.0.0"  # step 1, sub 1
    data = chunk.read_bytes()
    chunk.write_bytes(data[: len(data) // 2])
    error = _open_fails(
        archive_path,
        rf"step 1, camera 'rgb', sub 1: chunk file .*c\.3\.0\.0\.0 has {len(data) // 2} bytes, "
        rf"{len(data)} were committed",
    )
    assert str(archive_path) in str(error)


def test_missing_chunk(archive_path):
    (archive_path / "frames" / "depth" / "c.4.0.0.0").unlink()
    _open_fails(
        archive_path, r"step 2, camera 'depth', sub 0: chunk file .*c\.4\.0\.0\.0 is missing"
    )


def test_corrupt_chunk_is_found_when_read(archive_path):
    chunk = archive_path / "frames" / "rgb" / "c.2.0.0.0"  # step 1, sub 0
    data = bytearray(chunk.read_bytes())
    data[len(data) // 2] ^= 0x5A  # same size, one flipped byte: caught by zstd's checksum
    chunk.write_bytes(bytes(data))
    with Archive.open(archive_path) as archive:
        np.testing.assert_array_equal(archive.read_frame(1, "rgb", 1), _frame(CAMERAS["rgb"], 11))
        message = re.escape(f"{archive_path}: step 1, camera 'rgb', sub 0: chunk file ")
        with pytest.raises(ArchiveError, match=message + r".*c\.2\.0\.0\.0 is corrupt"):
            archive.read_frame(1, "rgb", 0)
        with pytest.raises(ArchiveError, match="is corrupt"):
            list(archive.iter_frames(steps=[1]))


def test_journal_damaged_in_the_middle(archive_path):
    journal = archive_path / "log" / "journal.jsonl"
    lines = journal.read_bytes().split(b"\n")
    lines[2] = lines[2].replace(b'"kind":"step"', b'"kind":"stop"')  # CRC no longer matches
    journal.write_bytes(b"\n".join(lines))
    offset = len(lines[0]) + len(lines[1]) + 2
    _open_fails(
        archive_path,
        rf"journal\.jsonl: line 3 \(byte {offset}\) is not a valid record \(seq 2 expected\) "
        "but more records follow",
    )


def test_missing_journal(archive_path):
    (archive_path / "log" / "journal.jsonl").unlink()
    _open_fails(archive_path, r"s\.zarr/log: missing journal journal\.jsonl")


def test_reading_what_is_not_there_names_what_is(archive_path):
    with Archive.open(archive_path) as archive:
        with pytest.raises(ArchiveError, match=r"step 7 is not committed \(3 steps are\)"):
            archive.read_frame(7, "rgb")
        with pytest.raises(ArchiveError, match=r"step 0 has no frames of camera 'ir'"):
            archive.read_frame(0, "ir")
        with pytest.raises(ArchiveError, match=r"camera 'rgb' has no sub 5; it has \[0, 1\]"):
            archive.read_frame(0, "rgb", 5)


def test_missing_log_folder_when_appending(archive_path):
    shutil.rmtree(archive_path / "log")
    with pytest.raises(ArchiveError, match=r"missing folder log/"):
        Archive.open(archive_path, mode="a")
    _open_fails(archive_path, r"s\.zarr/log: missing array metadata zarr\.json")


def test_a_failed_open_for_appending_writes_nothing(archive_path):
    (archive_path / "frames" / "rgb" / "c.0.0.0.0").unlink()
    journal = archive_path / "log" / "journal.jsonl"
    before = journal.read_bytes()
    with pytest.raises(ArchiveError, match="is missing"):
        Archive.open(archive_path, mode="a")
    assert journal.read_bytes() == before
    with pytest.raises(ArchiveError, match="is missing"):  # not "another process": unlocked
        Archive.open(archive_path, mode="a")
