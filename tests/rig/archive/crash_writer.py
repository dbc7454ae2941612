"""A session writer that the crash tests kill: appends deterministic steps.

Run as ``python crash_writer.py ARCHIVE FIRST LAST [--die-after-chunks STEP |
--die-mid-commit STEP]``. It creates ARCHIVE if missing (else opens it for
appending), appends steps FIRST..LAST-1 and prints ``committed N`` after each.
``--die-after-chunks`` SIGKILLs itself once STEP's chunks are written, before
its commit record; ``--die-mid-commit`` once half of STEP's commit line is
written. The test module imports the frame generators from here, so writer
and checker share one definition of every frame.
"""

import argparse
import functools
import os
import signal
import sys

import numpy as np

from rig.archive import Archive, FrameFormat, FrameRecord, StepRecord
from rig.archive import _journal as journal_module

CAMERAS = {
    "cam0": FrameFormat(120, 160, 3, "uint8"),
    "cam1": FrameFormat(24, 32, 1, "uint16"),
    "cam2": FrameFormat(60, 80, 2, "float32"),
}


@functools.cache
def _noise(variant: int, camera: str, sub: int) -> np.ndarray:
    fmt = CAMERAS[camera]
    rng = np.random.default_rng([variant, sorted(CAMERAS).index(camera), sub])
    if fmt.dtype == "float32":
        return rng.random(fmt.shape, dtype=np.float32)
    return rng.integers(0, np.iinfo(fmt.dtype).max, fmt.shape, dtype=fmt.dtype, endpoint=True)


def frame(step: int, camera: str, sub: int) -> np.ndarray:
    """The frame ``sub`` of ``camera`` at ``step``: pseudo-random, fixed by its ids.

    Noise drawn once per (step mod 5, camera, sub), so that making a frame
    costs next to nothing and a random kill almost always lands inside an
    append; the first pixel values carry the step index, so frames of
    different steps still differ.
    """
    image = _noise(step % 5, camera, sub).copy()
    image.reshape(-1)[:2] = (step % 251, step // 251)
    return image


def n_subs(step: int, camera: str) -> int:
    """Frames per camera and step: 1 to 4, varying (brackets, scan frames)."""
    return 1 + (step + sorted(CAMERAS).index(camera)) % 4


def step_record(step: int) -> StepRecord:
    return StepRecord(
        index=step,
        kind="mdf" if step % 2 else "btf",
        cameras=tuple(CAMERAS),
        views_deg={c: (15.0 * i, 7.5 * step % 360) for i, c in enumerate(CAMERAS)},
        light_deg=(30.0, (45.0 * step) % 360),
        actuators={"turntable_deg": 3.0 * step, "light_arc_deg": -1.25 * step},
        exposures_s=(0.01, 0.02, 0.04, 0.08),
        lamp=step % 8,
        laser="laser0" if step % 2 else None,
        started_at=1.7e9 + step,
    )


def step_frames(step: int) -> dict[str, list[FrameRecord]]:
    return {
        c: [
            FrameRecord(frame(step, c, s), sub=s, exposure_s=0.01 * 2**s, timestamp=1.7e9 + s)
            for s in range(n_subs(step, c))
        ]
        for c in CAMERAS
    }


def _die_in_commit(step: int, halfway: bool) -> None:
    """Patch the journal so the process SIGKILLs itself while committing ``step``."""
    original = journal_module.Journal.append

    def append(self, kind, payload, *, time):
        if kind == "step" and payload["step"]["index"] == step:
            if halfway:
                line = journal_module.encode_event(self._next_seq, time, kind, payload)
                os.write(self._fd, line[: len(line) // 2])
            os.kill(os.getpid(), signal.SIGKILL)
        return original(self, kind, payload, time=time)

    journal_module.Journal.append = append


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("archive")
    parser.add_argument("first", type=int)
    parser.add_argument("last", type=int)
    parser.add_argument("--die-after-chunks", type=int)
    parser.add_argument("--die-mid-commit", type=int)
    args = parser.parse_args()
    if args.die_after_chunks is not None:
        _die_in_commit(args.die_after_chunks, halfway=False)
    if args.die_mid_commit is not None:
        _die_in_commit(args.die_mid_commit, halfway=True)
    if os.path.exists(args.archive):
        archive = Archive.open(args.archive, mode="a", fsync=False)
    else:
        archive = Archive.create(
            args.archive, plan={"name": "crash"}, rig_config={}, cameras=CAMERAS, fsync=False
        )
    with archive:
        for step in range(args.first, args.last):
            archive.append_step(step_record(step), step_frames(step))
            sys.stdout.write(f"committed {step}\n")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
