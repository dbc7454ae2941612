"""A rig kind added in one file (docs/devices.md, "Adding a rig kind"): a fixed camera above
the sample and one fixed lamp. Registered with the rig model, the daemon and the simulator,
a plan compiles through it and a session runs on it through the daemon and the real drivers
against the simulated rig, with nothing else in the code knowing it."""

from __future__ import annotations

import numpy as np
import pytest

from orchestrator.daemon.kinds import DEVICE_SETS
from orchestrator.daemon.kinds.virtex import fixed_devices
from orchestrator.local import run_local
from rig import kinematics
from rig.archive import Archive
from rig.clock import VirtualClock
from rig.config import RigConfig
from rig.errors import PlanError
from rig.geometry import angular_distance_deg, direction_vector
from rig.kinds import KINDS, kind_names
from rig.plan import parse_plan
from rig.schedule import compile_axes, compile_plan
from rig.steps import AxesPose
from sim.kinds import SIM_KINDS
from sim.rig import SimulatedRig
from sim.scene import scene_from_dict

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


class ToyRig:
    """Camera ``cam0`` straight above, lamp ``lamp0`` of the light arc, the arc at 0°."""

    name = "toy"
    section = None
    device_roles = ("lamp_bank",)
    lamps_on_arc = True

    def config_defaults(self, data):
        return {"camera_arc": {"cameras": [{"id": "cam0", "theta_deg": 0.0}]}, **data}

    def check(self, config: RigConfig) -> None:
        if len(config.light_arc.lamps) != 1:
            raise ValueError("light_arc.lamps: the toy rig has one lamp")

    def lamps(self, config):
        return config.light_arc.lamps

    def device_section(self, config, role):
        return getattr(config, role)

    def with_device_sections(self, config, sections):
        return config.model_copy(update=dict(sections))

    def compile(self, plan, config):
        def inverse(config, view_deg, light_deg, *, sources="lamps"):
            lamp = config.lamps[0]
            pose = kinematics.RigPose(0.0, 0.0, "cam0", lamp.id)
            got_v, got_l = kinematics.forward(config, turntable_deg=0.0, arc_deg=0.0,
                                              camera="cam0", lamp=lamp.id)  # fmt: skip
            view_err = angular_distance_deg(direction_vector(*got_v), direction_vector(*view_deg))
            light_err = angular_distance_deg(direction_vector(*got_l), direction_vector(*light_deg))
            if max(view_err, light_err) > 0.5:
                raise PlanError("plan vs rig config", [f"({view_deg}, {light_deg}) is not ours"])
            return pose

        return compile_axes(plan, config, inverse=inverse, motion=self.motion_s)

    def motion_s(self, config, start, target):
        zero = np.zeros(np.broadcast(np.asarray(target[0]), np.asarray(target[1])).shape)
        return zero, zero

    def step_directions(self, config, step):
        views, light = {}, None
        for shot in step.shots:
            view, light = kinematics.forward(config, turntable_deg=0.0, arc_deg=0.0,
                                             camera=shot.camera, lamp=step.source)  # fmt: skip
            views[shot.camera] = (float(view[0]), float(view[1]))
        return views, (float(light[0]), float(light[1]))

    def inverse(self, config, view_deg, light_deg):
        return kinematics.inverse(config, view_deg, light_deg)

    def recorded_lamp_mm(self, config, lamp_id, actuators):
        return kinematics.lamp_position_mm(config, lamp_id, arc_deg=0.0, turntable_deg=0.0)

    def displaced_by_deg(self, config, actuators):
        return 0.0

    def posed_camera(self, config, camera_id, actuators):
        return None


class ToyWorld:
    def camera(self, config, camera_id, snapshot):
        return config.camera_model(camera_id)

    def lamp_mm(self, config, lamp_id, snapshot):
        return kinematics.lamp_position_mm(config, lamp_id, arc_deg=0.0, turntable_deg=0.0)


@pytest.fixture
def toy():
    KINDS.register("rig", "toy")(ToyRig())
    DEVICE_SETS.register("devices", "toy")(fixed_devices)  # nothing moves, as on a VirTex stage
    SIM_KINDS.register("sim", "toy")(ToyWorld())
    yield
    KINDS.unregister("rig", "toy")
    DEVICE_SETS.unregister("devices", "toy")
    SIM_KINDS.unregister("sim", "toy")


PLAN = '[sample]\nname = "toy"\n[captures.btf]\nviews = [[0, 0]]\nlights = [[30, 0]]\n'


def test_a_toy_kind_compiles_and_runs_a_plan(toy, tmp_path):
    assert "toy" in kind_names()
    lamps = {"light_arc": {"lamps": [{"id": "lamp0", "theta_deg": 30.0}]}}
    config = RigConfig.model_validate({"kind": "toy", **lamps})
    assert config.device_roles == ("lamp_bank",) and [c.id for c in config.camera_arc.cameras]
    (step,) = compile_plan(parse_plan(PLAN), config).steps
    assert (step.pose, step.source, step.cameras) == (AxesPose(0.0, 0.0), "lamp0", ("cam0",))
    with pytest.raises(PlanError, match="is not ours"):
        compile_plan(parse_plan(PLAN.replace("[[30, 0]]", "[[60, 0]]")), config)

    scene = scene_from_dict({
        "name": "toy", "effects": [], "sample": {"generator": "flat", "depth_mm": 0.01},
        "rig": {"kind": "toy", "overrides": lamps}, "render": {"scale": 0.05, "supersample": 1},
    })  # fmt: skip
    (tmp_path / "plan.toml").write_text(PLAN)
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as sim:
        final = run_local(tmp_path / "plan.toml", sim.rig_config(), archive=tmp_path / "t.zarr",
                          clock=clock)  # fmt: skip
    assert final["state"] == "done", final
    with Archive.open(tmp_path / "t.zarr") as archive:
        (record,) = archive.step_table()
        frame = archive.read_frame(record.index, "cam0", 0)
    assert record.lamp == "lamp0" and record.actuators == {}
    np.testing.assert_allclose(record.light_deg, (30.0, 0.0), atol=1e-9)
    assert frame.mean() > 10  # lit


def test_without_its_registration_the_kind_is_unknown():
    with pytest.raises(ValueError, match="unknown rig kind 'toy'"):
        RigConfig.model_validate({"kind": "toy"})
