"""Everything stored in an archive comes back after closing and reopening it."""

import json

import numpy as np
import pytest
import zarr

from rig.archive import (
    FRAME_TABLE_DTYPE,
    Archive,
    ArchiveError,
    FrameFormat,
    FrameRecord,
    StepAlreadyCommitted,
    StepRecord,
    software_versions,
)

CAMERAS = {
    "rgb": FrameFormat(24, 32, 3, "uint8"),
    "mono16": FrameFormat(20, 28, 1, "uint16"),
    "hdr": FrameFormat(12, 16, 3, "float32"),
}
PLAN = {"sample": {"name": "corduroy"}, "sampling": "H1", "captures": ["btf", "mdf"]}
PLAN_TOML = '# the plan file\n[sample]\nname = "corduroy"\n'
RIG = {"turntable": {"port": "/dev/ttyUSB0", "speed_deg_s": 30.0}, "cameras": 3}


def image(fmt: FrameFormat, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if fmt.dtype == "float32":
        # Extreme float values must survive bit-exactly too.
        values = rng.normal(0, 1e3, fmt.shape).astype(np.float32)
        values.flat[:3] = [np.finfo(np.float32).max, np.finfo(np.float32).tiny, -0.0]
        return values
    return rng.integers(0, np.iinfo(fmt.dtype).max, fmt.shape, dtype=fmt.dtype, endpoint=True)


def step(index: int, cameras=tuple(CAMERAS), **fields) -> StepRecord:
    defaults = {
        "kind": "btf",
        "views_deg": {c: (15.0 * i, 90.0 + index) for i, c in enumerate(cameras)},
        "light_deg": (45.0, 359.5),
        "actuators": {"turntable_deg": 12.5 * index, "light_arc_deg": -30.0},
        "exposures_s": (0.004, 0.016),
        "lamp": 3,
        "laser": "left",
        "started_at": 1.7e9 + index,
    }
    return StepRecord(index=index, cameras=cameras, **{**defaults, **fields})


@pytest.fixture
def session(tmp_path):
    """An archive with three steps; yields its path and the frames given per (step, camera)."""
    path = tmp_path / "session.zarr"
    given = {}
    with Archive.create(
        path,
        plan=PLAN,
        plan_toml=PLAN_TOML,
        rig_config=RIG,
        cameras=CAMERAS,
        calibration={"K": np.eye(3), "dist": np.zeros(5, np.float32)},
    ) as archive:
        for index in range(3):
            frames = {}
            for c, fmt in CAMERAS.items():
                frames[c] = [
                    FrameRecord(
                        image(fmt, 100 * index + s),
                        sub=s,
                        exposure_s=0.004 * 4**s,
                        timestamp=1.7e9 + index + s / 10,
                    )
                    for s in range(1 + index)
                ]
                given[(index, c)] = frames[c]
            archive.append_step(step(index), frames)
    return path, given


def test_every_field_round_trips(session):
    path, given = session
    with Archive.open(path) as archive:
        assert archive.plan == PLAN
        assert archive.plan_toml == PLAN_TOML
        assert archive.rig_config == RIG
        assert archive.cameras == CAMERAS
        assert archive.calibration == {"K": np.eye(3).tolist(), "dist": [0.0] * 5}
        assert archive.calibration_version == 1
        assert archive.software == software_versions()
        assert archive.committed_steps() == (0, 1, 2)
        for record in archive.step_table():
            assert record.committed_at >= record.started_at
            assert record == StepRecord.from_json(
                {**step(record.index).to_json(), "committed_at": record.committed_at}
            )
        for (index, camera), frames in given.items():
            for frame in frames:
                stored = archive.read_frame(index, camera, frame.sub)
                assert stored.dtype == frame.image.dtype
                np.testing.assert_array_equal(stored, frame.image, strict=True)
        table = archive.frame_table()
        assert table.dtype == FRAME_TABLE_DTYPE
        assert len(table) == sum(len(f) for f in given.values())
        for row in table:
            frame = given[(int(row["step"]), str(row["camera"]))][int(row["sub"])]
            assert row["exposure_s"] == frame.exposure_s
            assert row["timestamp"] == frame.timestamp
        # Positions number each camera's frames 0, 1, … in commit order.
        for camera in CAMERAS:
            positions = table["position"][table["camera"] == camera]
            np.testing.assert_array_equal(positions, np.arange(len(positions)))
        kinds = [e.kind for e in archive.events()]
        assert kinds == ["created", "calibration", "step", "step", "step", "closed"]
        assert [e.seq for e in archive.events()] == list(range(6))


def test_iter_frames_selects_by_step_and_camera(session):
    path, given = session
    with Archive.open(path) as archive:
        seen = [
            (i.step, i.camera, i.sub) for i, _ in archive.iter_frames(steps=[2], cameras=["hdr"])
        ]
        assert seen == [(2, "hdr", 0), (2, "hdr", 1), (2, "hdr", 2)]
        for info, frame in archive.iter_frames():
            np.testing.assert_array_equal(frame, given[(info.step, info.camera)][info.sub].image)


def test_zarr_reads_the_same_frames_and_metadata(session):
    path, _ = session
    root = zarr.open_group(path, mode="r")
    assert sorted(name for name, _ in root.members()) == [
        "calibration",
        "frames",
        "log",
        "material",
    ]
    assert root.attrs["plan"] == PLAN
    assert root["calibration"].attrs["version"] == 1
    with Archive.open(path) as archive:
        for row in archive.frame_table():
            array = root[f"frames/{row['camera']}"]
            assert array.shape[0] == 6  # trimmed to the committed frames on close
            zarr_frame = array[int(row["position"])]
            np.testing.assert_array_equal(
                zarr_frame,
                archive.read_frame(int(row["step"]), str(row["camera"]), int(row["sub"])),
            )


def test_bare_arrays_take_sub_and_exposure_from_their_order(tmp_path):
    fmt = CAMERAS["rgb"]
    with Archive.create(
        tmp_path / "a.zarr", plan={}, rig_config={}, cameras={"rgb": fmt}
    ) as archive:
        bracket = [image(fmt, s) for s in range(3)]
        archive.append_step(step(0, ("rgb",), exposures_s=(0.001, 0.01, 0.1)), {"rgb": bracket})
        archive.append_step(step(1, ("rgb",), exposures_s=(0.5,)), {"rgb": bracket[:2]})
        table = archive.frame_table()
        np.testing.assert_array_equal(table["sub"], [0, 1, 2, 0, 1])
        np.testing.assert_array_equal(table["exposure_s"], [0.001, 0.01, 0.1, 0.5, 0.5])
        np.testing.assert_array_equal(archive.read_frame(0, "rgb", 2), bracket[2])
        with pytest.raises(ArchiveError, match="bare frame 2 has no exposure"):
            archive.append_step(step(2, ("rgb",)), {"rgb": bracket})


def test_resume_continues_and_refuses_committed_steps(session):
    path, _ = session
    with Archive.open(path, mode="a") as archive:
        frames = {c: [image(f, 7)] for c, f in CAMERAS.items()}
        with pytest.raises(StepAlreadyCommitted, match="step 1 is already committed") as err:
            archive.append_step(step(1), frames)
        assert (err.value.index, err.value.next_index) == (1, 3)
        archive.append_step(step(3), frames)
        assert archive.committed_steps() == (0, 1, 2, 3)
    with Archive.open(path) as archive:
        np.testing.assert_array_equal(archive.read_frame(3, "hdr"), frames["hdr"][0])
        assert [e.kind for e in archive.events()][-3:] == ["opened", "step", "closed"]


def test_calibration_is_versioned(session):
    path, _ = session
    with Archive.open(path, mode="a") as archive:
        assert archive.set_calibration({"K": [[2.0]]}) == 2
        assert archive.calibration == {"K": [[2.0]]}
    with Archive.open(path) as archive:
        assert archive.calibration_version == 2
        history = [e.payload for e in archive.events("calibration")]
        assert [h["version"] for h in history] == [1, 2]
        assert history[0]["calibration"]["dist"] == [0.0] * 5
    mirror = json.loads((path / "calibration" / "zarr.json").read_text())["attributes"]
    assert mirror == {"version": 2, "calibration": {"K": [[2.0]]}}


def test_events_are_appended_with_sequence_numbers(session):
    path, _ = session
    with Archive.open(path, mode="a") as archive:
        event = archive.log_event("lamp_fault", lamp=3, current_a=np.float32(0.5))
        assert event.payload == {"lamp": 3, "current_a": 0.5}
        with pytest.raises(ArchiveError, match="event kind 'step'"):
            archive.log_event("step", index=9)
        with pytest.raises(ArchiveError, match="cannot store"):
            archive.log_event("telemetry", temperature_c=float("nan"))
    with Archive.open(path) as archive:
        (stored,) = archive.events("lamp_fault")
        assert stored == event
        assert [e.seq for e in archive.events()] == list(range(len(archive.events())))


def _write_then_fail(archive):
    with archive.replace_material("normals") as group:
        group.create_array("map", data=np.zeros((4, 4, 3), np.float32))
        raise RuntimeError("worker died")


def test_material_results_are_replaced_whole(session):
    path, _ = session
    with Archive.open(path, mode="a") as archive:
        with archive.replace_material("normals") as group:
            group.create_array("map", data=np.ones((4, 4, 3), np.float32))
        with pytest.raises(RuntimeError, match="worker died"):
            _write_then_fail(archive)
        np.testing.assert_array_equal(archive.material["normals/map"][:], 1.0)
        with archive.replace_material("normals") as group:
            group.create_array("map", data=np.full((2, 2, 3), 2.0, np.float32))
        assert archive.material["normals/map"].shape == (2, 2, 3)
        with pytest.raises(ArchiveError, match=r"material result name '\.\./x'"):
            archive.replace_material("../x").__enter__()
    assert sorted(p.name for p in (path / "material").iterdir()) == ["normals", "zarr.json"]


def test_read_only_and_single_writer(session):
    path, _ = session
    with Archive.open(path) as reader:
        with pytest.raises(ArchiveError, match="not open for appending"):
            reader.log_event("note", text="x")
        with pytest.raises(ValueError, match="read-only"):  # zarr's own refusal
            reader.material.create_array("x", shape=(1,), dtype="u1")
    with Archive.open(path, mode="a"), pytest.raises(ArchiveError, match="another process"):
        Archive.open(path, mode="a")


@pytest.mark.parametrize(
    ("frames", "message"),
    [
        ({"rgb": [np.zeros((24, 32, 3), np.uint16)]}, r"got a uint16 frame .* delivers uint8"),
        ({"rgb": [np.zeros((24, 31, 3), np.uint8)]}, r"shape \(24, 31, 3\).*\(24, 32, 3\)"),
        ({"rgb": [[0, 1]]}, "expected a numpy array, got list"),
        ({"rgb": []}, "camera 'rgb': no frames"),
        ({"ir": [np.zeros((24, 32, 3), np.uint8)]}, r"frames given for cameras \['ir'\]"),
        (
            {"rgb": [FrameRecord(np.zeros((24, 32, 3), np.uint8), exposure_s=float("inf"))]},
            "exposure_s = inf",
        ),
        (
            {"rgb": [FrameRecord(np.zeros((24, 32, 3), np.uint8), sub=1)] * 2},
            r"repeated sub-indices \[1, 1\]",
        ),
    ],
)
def test_bad_frames_are_refused_and_nothing_is_committed(tmp_path, frames, message):
    cameras = {"rgb": CAMERAS["rgb"]}
    with Archive.create(tmp_path / "a.zarr", plan={}, rig_config={}, cameras=cameras) as archive:
        with pytest.raises(ArchiveError, match=message):
            archive.append_step(step(0, ("rgb",)), frames)
        assert archive.committed_steps() == ()


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"index": -1}, "index = -1"),
        ({"kind": ""}, "kind = ''"),
        ({"light_deg": (200.0, 0.0)}, "light_deg θ = 200.0°"),
        ({"actuators": {"rail_mm": float("nan")}}, r"actuators\['rail_mm'\] = nan"),
        ({"exposures_s": (0.0,)}, "each must be > 0"),
        ({"lamp": 2.5}, "lamp = 2.5"),
        ({"views_deg": {"ir": (0.0, 0.0)}}, "views_deg names camera 'ir'"),
    ],
)
def test_bad_step_records_name_the_field(fields, message):
    with pytest.raises(ArchiveError, match=message):
        StepRecord(**{"index": 0, "kind": "btf", "cameras": ("rgb",), **fields})


def test_create_refuses_bad_arguments(tmp_path):
    with pytest.raises(ArchiveError, match=r"FrameFormat\.dtype = 'int8'"):
        FrameFormat(8, 8, 1, "int8")
    with pytest.raises(ArchiveError, match=r"plan: cannot store .*object"):
        Archive.create(tmp_path / "a.zarr", plan={"x": object()}, rig_config={}, cameras=CAMERAS)
    assert not (tmp_path / "a.zarr").exists()
    Archive.create(tmp_path / "b.zarr", plan={}, rig_config={}, cameras=CAMERAS).close()
    with pytest.raises(ArchiveError, match="already exists"):
        Archive.create(tmp_path / "b.zarr", plan={}, rig_config={}, cameras=CAMERAS)
