"""Read rig configs written in an older layout: each is migrated to the current one.

Layout 1 (no ``version`` field; configs from before the device registry, and
every archive recorded then) kept a role's connection and its wiring apart:
``[turntable.drive]`` + ``[turntable.registers]``, ``[lamp_bank.connection]`` +
``[lamp_bank.registers]``, ``[light_arc.servos]`` + ``light_arc.servo_*``,
``[laser.brick]`` + the laser's NXT wiring fields, and a camera connection
without ``kind`` meant the simulator's camera server. Layout 2 puts each
role's device in one tagged section, ``[ROLE.device]`` with a ``kind``.

The migration works on the data, before validation, and moves only what it
finds, so a layout-2 file that omits ``version`` reads as it is.
"""

from __future__ import annotations

from typing import Any

__all__ = ["CONFIG_VERSION", "migrate_rig_config"]

CONFIG_VERSION = 2

# role: (its kind in layout 1, the old connection section, {old field: device field})
_V1_DEVICES: dict[str, tuple[str, str, dict[str, str]]] = {
    "turntable": ("modbus", "drive", {"registers": "registers"}),
    "lamp_bank": ("modbus", "connection", {"registers": "registers"}),
    "light_arc": (
        "dynamixel",
        "servos",
        {
            "servo_ids": "ids",
            "servo_ticks_per_rev": "ticks_per_rev",
            "servo_gear_ratio": "gear_ratio",
            "servo_zero_tick": "zero_tick",
            "servo_profile_velocity": "profile_velocity",
            "servo_profile_acceleration": "profile_acceleration",
        },
    ),
    "laser": (
        "nxt",
        "brick",
        {
            name: name
            for name in (
                "motor_port",
                "laser_port",
                "gear_ratio",
                "motor_power",
                "laser_power",
                "min_battery_mv",
                "stall_timeout_s",
            )
        },
    ),
}


def migrate_rig_config(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` (a rig config as read from TOML or JSON) in the current layout.

    Raises ``ValueError`` (reported by validation as a config error) for a
    ``version`` newer than this software or a section that mixes both layouts.
    """
    version = data.get("version", 1)
    if version == CONFIG_VERSION:
        return data
    if version != 1:
        raise ValueError(
            f"version {version!r}: this software reads rig config layouts 1 and "
            f"{CONFIG_VERSION}; write version = {CONFIG_VERSION} or update btfrig"
        )
    data = dict(data)
    for role, (kind, connection, fields) in _V1_DEVICES.items():
        section = data.get(role)
        if isinstance(section, dict):
            data[role] = _device_section(role, section, kind, connection, fields)
    arc = data.get("camera_arc")
    if isinstance(arc, dict) and isinstance(arc.get("cameras"), list):
        data["camera_arc"] = {**arc, "cameras": [_camera(c) for c in arc["cameras"]]}
    data["version"] = CONFIG_VERSION
    return data


def _device_section(
    role: str, section: dict, kind: str, connection: str, fields: dict[str, str]
) -> dict:
    old = [key for key in (connection, *fields) if key in section]
    if not old:
        return section
    if "device" in section:
        raise ValueError(
            f"{role}: {old} (layout 1) and {role}.device (layout 2) together; "
            f"move {old} into [{role}.device]"
        )
    section = dict(section)
    link = section.pop(connection, {})
    device = {"kind": kind, **link} if isinstance(link, dict) else link
    if isinstance(device, dict):
        for old_key, new_key in fields.items():
            if old_key in section:
                device[new_key] = section.pop(old_key)
    section["device"] = device
    return section


def _camera(camera: Any) -> Any:
    connection = camera.get("connection") if isinstance(camera, dict) else None
    if not isinstance(connection, dict):
        return camera
    connection = dict(connection)
    connection.setdefault("kind", "sim")
    if connection.get("cti", "") is None:  # layout 1 stored cti = null for every kind
        del connection["cti"]
    return {**camera, "connection": connection}
