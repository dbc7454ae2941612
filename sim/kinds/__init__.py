"""Each rig kind's part of the simulated world, found by the config's ``kind`` (``rig.kinds``).

What the simulator must know of a kind beyond its config: where a world
snapshot (axes, arm, rail) puts a camera and a lamp in the sample frame. A
module per kind registers one object at import
(``SIM_KINDS.register("sim", name)``) with three methods:

- ``camera(config, camera_id, snapshot) -> PinholeCamera``: the camera's model in
  the sample frame (a rig of axes: with the turntable at 0, the renderer turns it);
- ``lamp_mm(config, lamp_id, snapshot) -> (3,) ndarray``: the lamp's position (mm);
- ``mount_offset_mm(config, offset_mm, snapshot) -> (3,) ndarray``: a lamp's offset
  from its place, given in its mount's frame (``sim.as_built``; the frame in which
  ``rig calibrate lamps`` reports positions), in the sample frame at the snapshot.
"""

from __future__ import annotations

from rig.errors import ConfigError
from rig.registry import KindRegistry

__all__ = ["SIM_KINDS", "sim_kind"]

SIM_KINDS = KindRegistry("sim.kinds", roles=("sim",))


def sim_kind(kind: str):
    """The simulator's part of rig kind ``kind``; ``ConfigError`` naming those served."""
    entry = SIM_KINDS.lookup("sim", kind)
    if entry is None:
        raise ConfigError(
            f"the simulator has no {kind!r} rig; it serves {SIM_KINDS.served('sim')}"
        )
    return entry
