"""The turntable and lamp-bank register maps in the rig config: validation and TOML."""

import re
import tomllib
from pathlib import Path

import pytest
from pydantic import ValidationError

from rig.config import RigConfig
from rig.devices import DriveRegisters, LampBankRegisters


def test_defaults_are_the_documented_map():
    r = DriveRegisters()
    assert (r.target_position, r.actual_position, r.status, r.command) == (0, 2, 4, 5)
    assert (r.speed, r.acceleration, r.units_per_deg, r.word_order) == (6, 7, 100.0, "high_first")
    assert (r.moving_bit, r.in_position_bit, r.fault_bit, r.homed_bit) == (0, 1, 2, 3)
    assert (r.go_code, r.home_code, r.stop_code) == (1, 2, 3)


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"status": 1}, r"registers target_position and status overlap at \[1\]"),
        ({"command": 3}, r"registers actual_position and command overlap at \[3\]"),
        ({"fault_bit": 0}, r"status bits must differ; got .* = \[0, 1, 0, 3\]"),
        ({"stop_code": 1}, r"command codes must differ; got go/home/stop = \[1, 2, 1\]"),
        ({"units_per_deg": 0}, "greater than 0"),
    ],
)
def test_bad_maps_name_the_fields(fields, message):
    with pytest.raises(ValidationError, match=message):
        DriveRegisters(**fields)


def test_a_rig_toml_section_sets_the_map():
    text = """
    [turntable.device]
    kind = "modbus"
    protocol = "rtu"
    serial_port = "/dev/ttyUSB0"
    baudrate = 38400
    unit_id = 3

    [turntable.device.registers]
    target_position = 0x20
    actual_position = 0x22
    status = 0x24
    command = 0x25
    speed = 0x26
    acceleration = 0x27
    units_per_deg = 10
    word_order = "low_first"

    [lamp_bank.device]
    kind = "modbus"
    host = "192.168.0.20"
    port = 502
    """
    config = RigConfig.model_validate(tomllib.loads(text))
    assert config.turntable.device.serial_port == "/dev/ttyUSB0"
    assert config.turntable.device.registers.status == 0x24
    assert config.turntable.device.registers.word_order == "low_first"
    assert config.lamp_bank.device.host == "192.168.0.20"


def test_lamp_bank_layout_defaults():
    r = LampBankRegisters()
    assert (r.coils, r.light_sensors, r.dimming, r.dim_full_scale) == (0, 0, False, 1000)


def test_the_real_hardware_example_in_the_readme_is_a_valid_rig_config():
    readme = (Path(__file__).parents[3] / "README.md").read_text()
    section = readme.split("## Pointing rig at real hardware", 1)[1]
    block = re.search(r"```toml\n(.*?)```", section, re.S).group(1)
    config = RigConfig.model_validate(tomllib.loads(block))
    assert config.version == 2
    assert config.turntable.device.protocol == "rtu"
    assert config.light_arc.device.ids == (1, 2)
    assert config.laser.device.transport == "usb"
    assert config.camera("cam0").connection.kind == "genicam"
