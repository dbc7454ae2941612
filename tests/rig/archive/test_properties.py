"""Property tests: any valid step and frame table survives the archive unchanged."""

import json
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from rig.archive import Archive, FrameFormat, FrameRecord, StepRecord

CAMERAS = {
    "c8": FrameFormat(3, 4, 3, "uint8"),
    "c16": FrameFormat(2, 5, 1, "uint16"),
    "cf": FrameFormat(4, 2, 2, "float32"),
}
finite = st.floats(allow_nan=False, allow_infinity=False)
ident = st.none() | st.integers(-(2**53), 2**53) | st.text(max_size=8)


@st.composite
def steps(draw, index: int) -> StepRecord:
    cameras = draw(st.lists(st.sampled_from(sorted(CAMERAS)), min_size=1, unique=True))
    direction = st.tuples(st.floats(0.0, 180.0), finite)
    return StepRecord(
        index=index,
        kind=draw(st.text(min_size=1, max_size=12)),
        cameras=tuple(cameras),
        views_deg=draw(st.dictionaries(st.sampled_from(cameras), direction)),
        light_deg=draw(st.none() | direction),
        actuators=draw(st.dictionaries(st.text(max_size=10), finite, max_size=4)),
        exposures_s=tuple(draw(st.lists(st.floats(1e-9, 1e4), max_size=5))),
        lamp=draw(ident),
        laser=draw(ident),
        started_at=draw(finite),
    )


@st.composite
def frame_lists(draw, step: StepRecord) -> dict[str, list[FrameRecord]]:
    frames = {}
    for camera in step.cameras:
        fmt = CAMERAS[camera]
        subs = draw(st.lists(st.integers(0, 10_000), min_size=1, max_size=4, unique=True))
        frames[camera] = []
        for sub in subs:
            raw = draw(st.binary(min_size=fmt.nbytes, max_size=fmt.nbytes))
            # Any bit pattern, NaN payloads included, must come back byte for byte.
            image = np.frombuffer(raw, dtype=fmt.dtype).reshape(fmt.shape)
            record = FrameRecord(
                image, sub=sub, exposure_s=draw(st.floats(0.0, 1e4)), timestamp=draw(finite)
            )
            frames[camera].append(record)
    return frames


@st.composite
def sessions(draw) -> list[tuple[StepRecord, dict[str, list[FrameRecord]]]]:
    indices = draw(st.lists(st.integers(0, 10**9), min_size=1, max_size=4, unique=True))
    session = []
    for index in indices:  # committed in any order, not only ascending
        step = draw(steps(index))
        session.append((step, draw(frame_lists(step))))
    return session


@given(steps(7))
def test_step_record_json_round_trip(step):
    assert StepRecord.from_json(json.loads(json.dumps(step.to_json()))) == step


@given(sessions())
def test_step_and_frame_tables_round_trip(session):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "s.zarr"
        with Archive.create(path, plan={}, rig_config={}, cameras=CAMERAS, fsync=False) as archive:
            for step, frames in session:
                archive.append_step(step, frames)
        with Archive.open(path) as archive:
            by_index = dict(sorted((s.index, (s, f)) for s, f in session))
            table = archive.step_table()
            assert [s.index for s in table] == list(by_index)
            expected_rows = []
            for stored in table:
                step, frames = by_index[stored.index]
                assert stored == StepRecord.from_json(
                    {**step.to_json(), "committed_at": stored.committed_at}
                )
                for camera in step.cameras:
                    for record in sorted(frames[camera], key=lambda r: r.sub):
                        expected_rows.append(
                            (step.index, camera, record.sub, record.exposure_s, record.timestamp)
                        )
                        image = archive.read_frame(step.index, camera, record.sub)
                        assert image.tobytes() == record.image.tobytes()
            frame_table = archive.frame_table()
            rows = [
                (int(r["step"]), str(r["camera"]), int(r["sub"]), r["exposure_s"], r["timestamp"])
                for r in frame_table
            ]
            assert rows == expected_rows
            for camera in CAMERAS:
                positions = np.sort(frame_table["position"][frame_table["camera"] == camera])
                np.testing.assert_array_equal(positions, np.arange(len(positions)))
