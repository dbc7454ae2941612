"""Each rig kind's device set, found by the config's ``kind`` (``rig.kinds``).

A module per kind registers, at import, the function that composes the opened
drivers of its roles (``RigConfig.device_roles``) into the ``DeviceSet`` a
session drives: ``DEVICE_SETS.register("devices", name)``. ``build_devices``
opens the roles and asks here; the first lookup of an unknown kind imports
every module of this package.
"""

from __future__ import annotations

from rig.registry import KindRegistry

__all__ = ["DEVICE_SETS"]

#: ``(config, *, clock, lamps, cameras, **opened roles) -> DeviceSet`` by rig kind.
DEVICE_SETS = KindRegistry("orchestrator.daemon.kinds", roles=("devices",))
