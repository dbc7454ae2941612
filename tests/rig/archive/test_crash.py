"""A writer SIGKILLed in the middle of an append leaves only whole steps visible.

The writer runs in a child process (``crash_writer.py``); the test kills it
at a random moment, or it kills itself at a chosen point of the commit
protocol, then the archive is reopened, checked frame by frame against the
frames the writer was given, and appended to again.
"""

import importlib.util
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rig.archive import Archive, StepAlreadyCommitted

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow

_RANDOM_KILLS = 8
WRITER_PATH = Path(__file__).with_name("crash_writer.py")
_spec = importlib.util.spec_from_file_location("archive_crash_writer", WRITER_PATH)
writer = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(writer)


def _run_writer(archive: Path, first: int, last: int, *options: str) -> tuple[int, list[int]]:
    """Run the writer to its end; its exit code and the steps it reported."""
    with subprocess.Popen(
        [sys.executable, str(WRITER_PATH), str(archive), str(first), str(last), *options],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    ) as proc:
        out, err = proc.communicate(timeout=120)
    committed = [int(line.split()[1]) for line in out.splitlines()]
    assert proc.returncode in (0, -signal.SIGKILL), err
    return proc.returncode, committed


def _kill_writer_at_random(archive: Path, first: int, rng: random.Random) -> list[int]:
    """Start the writer, SIGKILL it a random moment after it committed two steps.

    Returns every step the writer reported committed before it died.
    """
    with subprocess.Popen(
        [sys.executable, str(WRITER_PATH), str(archive), str(first), str(first + 10_000)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    ) as proc:
        committed = []
        while len(committed) < 2:
            line = proc.stdout.readline()
            assert line, f"writer ended early: {proc.stderr.read()}"
            committed.append(int(line.split()[1]))
        # Steps take a few ms each, so the kill lands anywhere within one. (The
        # pipe stays open: a closed one would end the writer by EPIPE instead.)
        time.sleep(rng.uniform(0.0, 0.02))
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
        committed += [int(line.split()[1]) for line in proc.stdout.read().splitlines()]
    assert proc.returncode == -signal.SIGKILL
    return committed


def _assert_whole_steps(archive_path: Path, *, at_least: int) -> int:
    """Committed steps are 0..n-1, each bit-exact in every field and frame; returns n."""
    with Archive.open(archive_path) as archive:
        committed = archive.committed_steps()
        assert committed == tuple(range(len(committed)))
        assert len(committed) >= at_least
        for record in archive.step_table():
            expected = writer.step_record(record.index)
            assert record.committed_at is not None
            assert record == type(record).from_json(
                {**expected.to_json(), "committed_at": record.committed_at}
            )
        n_frames = 0
        for info, image in archive.iter_frames():
            np.testing.assert_array_equal(image, writer.frame(info.step, info.camera, info.sub))
            n_frames += 1
        expected_frames = sum(writer.n_subs(s, c) for s in committed for c in writer.CAMERAS)
        assert n_frames == expected_frames
    return len(committed)


def test_kill_at_random_moments_then_resume(tmp_path):
    archive = tmp_path / "session.zarr"
    rng = random.Random(20240607)
    n = 0
    for _ in range(_RANDOM_KILLS):
        reported = _kill_writer_at_random(archive, n, rng)
        # Every step the writer reported is committed; at most one more made it.
        visible = _assert_whole_steps(archive, at_least=reported[-1] + 1)
        assert visible in (reported[-1] + 1, reported[-1] + 2)
        n = visible
    code, reported = _run_writer(archive, n, n + 3)
    assert code == 0
    assert reported == [n, n + 1, n + 2]
    assert _assert_whole_steps(archive, at_least=n + 3) == n + 3
    with Archive.open(archive) as reopened:
        recoveries = [e.payload["recovered"] for e in reopened.events("opened")]
        assert reopened.events()[-1].kind == "closed"
    # A reopening after a kill that landed inside an append finds what it left half
    # done (chunk files of an uncommitted step, or a torn journal line). About 3 in
    # 5 kills land there, so at least one of 8 must (all 8 missing: p < 0.1 %).
    assert len(recoveries) == _RANDOM_KILLS
    assert any(recoveries), recoveries


def test_kill_after_chunks_before_commit(tmp_path):
    archive = tmp_path / "session.zarr"
    code, reported = _run_writer(archive, 0, 6, "--die-after-chunks", "3")
    assert code == -signal.SIGKILL
    assert reported == [0, 1, 2]
    # Step 3's chunks are on disk (the kill really came mid-append) but not visible.
    cam0 = archive / "frames" / "cam0"
    committed_cam0 = sum(writer.n_subs(s, "cam0") for s in range(3))
    leftovers = [cam0 / f"c.{committed_cam0 + i}.0.0.0" for i in range(writer.n_subs(3, "cam0"))]
    assert all(p.exists() for p in leftovers)
    contents = [p.read_bytes() for p in leftovers]
    assert _assert_whole_steps(archive, at_least=3) == 3
    with Archive.open(archive, mode="a") as resumed:
        recovered = resumed.events("opened")[-1].payload["recovered"]
        assert recovered["uncommitted_chunks/cam0"] == len(leftovers)
        assert not any(p.exists() for p in leftovers)
        # Set aside, not deleted: the same bytes under quarantine/<time>/frames/cam0/.
        kept = archive / recovered["quarantine"] / "frames" / "cam0"
        assert [(kept / p.name).read_bytes() for p in leftovers] == contents
        with pytest.raises(StepAlreadyCommitted, match="step 2 is already committed"):
            resumed.append_step(writer.step_record(2), writer.step_frames(2))
    code, reported = _run_writer(archive, 3, 5)
    assert (code, reported) == (0, [3, 4])
    assert _assert_whole_steps(archive, at_least=5) == 5


def test_kill_halfway_through_the_commit_record(tmp_path):
    archive = tmp_path / "session.zarr"
    code, reported = _run_writer(archive, 0, 6, "--die-mid-commit", "2")
    assert (code, reported) == (-signal.SIGKILL, [0, 1])
    journal = archive / "log" / "journal.jsonl"
    assert not journal.read_bytes().endswith(b"\n")  # the torn half line is there
    assert _assert_whole_steps(archive, at_least=2) == 2
    with Archive.open(archive, mode="a") as resumed:
        recovered = resumed.events("opened")[-1].payload["recovered"]
        assert recovered["torn_journal_bytes"] > 0
        resumed.append_step(writer.step_record(2), writer.step_frames(2))
    assert journal.read_bytes().endswith(b"\n")
    assert _assert_whole_steps(archive, at_least=3) == 3
