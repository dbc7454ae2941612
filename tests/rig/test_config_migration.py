"""Rig configs in layout 1 (before the device sections were tagged unions) still load."""

import json
import re
import tomllib
from pathlib import Path

import pytest

from rig.config import RigConfig, load_rig_config, write_rig_config
from rig.errors import ConfigError

ROOT = Path(__file__).parents[2]

# The README's hardware example as it was written in layout 1.
LAYOUT_1_HARDWARE = """
[turntable.drive]
protocol = "rtu"
serial_port = "/dev/ttyUSB0"
baudrate = 38400
unit_id = 1
retry = { timeout_s = 0.5, retries = 3, backoff_s = 0.1 }

[turntable.registers]
target_position = 0
actual_position = 2
status = 4
command = 5
speed = 6
acceleration = 7
units_per_deg = 100.0
word_order = "high_first"
go_code = 1
home_code = 2
stop_code = 3

[lamp_bank.connection]
protocol = "tcp"
host = "192.168.10.20"
port = 502
unit_id = 1

[light_arc]
servo_ids = [1, 2]
servo_gear_ratio = 5.0
servo_zero_tick = 0

[light_arc.servos]
serial_port = "/dev/serial/by-id/usb-FTDI_USB__-__Serial_Converter_FT1234-if00-port0"
baudrate = 57600

[laser]
gear_ratio = 0.041666667
min_battery_mv = 6800

[laser.brick]
transport = "usb"
retry = { timeout_s = 0.5, retries = 3, backoff_s = 0.1 }

[[camera_arc.cameras]]
id = "cam0"
theta_deg = 0.0
width = 2048
height = 1536
channels = 1
bit_depth = 12
connection = { kind = "genicam", url = "22051234", cti = "/opt/vendor/lib/GenTL.cti" }
"""


def _readme_example() -> dict:
    section = (ROOT / "README.md").read_text().split("## Pointing rig at real hardware", 1)[1]
    return tomllib.loads(re.search(r"```toml\n(.*?)```", section, re.S).group(1))


def test_the_readme_example_is_layout_2():
    assert _readme_example()["version"] == 2


def test_a_layout_1_file_reads_as_the_same_rig_as_its_layout_2_form(tmp_path):
    path = tmp_path / "old.toml"
    path.write_text(LAYOUT_1_HARDWARE)
    old = load_rig_config(path)
    assert old == RigConfig.model_validate(_readme_example())
    assert old.light_arc.device.gear_ratio == 5.0
    assert old.laser.device.min_battery_mv == 6800
    # written back, it is layout 2 and reads back equal
    again = load_rig_config(write_rig_config(old, tmp_path / "new.toml"))
    assert tomllib.loads((tmp_path / "new.toml").read_text())["version"] == 2
    assert again == old


def test_a_config_stored_by_an_archive_in_layout_1_loads():
    # model_dump(mode="json") of the default rig as the layout-1 software stored it
    # (sim cameras with cti = null, the drive on a pty)
    stored = json.loads((Path(__file__).parent / "data" / "rig_config_layout1.json").read_text())
    assert "version" not in stored and "drive" in stored["turntable"]
    config = RigConfig.model_validate(stored)
    assert config.turntable.device.kind == "modbus"
    assert config.turntable.device.serial_port == "/dev/pts/7"
    assert config.light_arc.device.ids == (1,)
    assert config.laser.device.motor_port == "A"
    assert all(cam.connection.kind == "sim" for cam in config.camera_arc.cameras)
    assert config.model_copy(update={"turntable": RigConfig().turntable}) == RigConfig()


def test_a_layout_1_camera_without_kind_is_a_sim_camera():
    config = RigConfig.model_validate(
        {
            "camera_arc": {
                "cameras": [{"id": "c", "theta_deg": 0, "connection": {"url": "tcp://h:1"}}]
            }
        }
    )
    assert config.camera("c").connection.kind == "sim"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "[turntable.drive]\nport = 1\n[turntable.device]\nkind = 'modbus'",
            r"turntable: \['drive'\] \(layout 1\) and turntable.device",
        ),
        ("version = 3", r"version 3: this software reads rig config layouts 1 and 2"),
        (
            "[turntable.device]\nkind = 'canopen'",
            r"turntable.device: kind 'canopen' is not known here; valid kinds are 'modbus'",
        ),
        (
            "[light_arc.device]\nids = [1]",
            r"light_arc.device: kind is missing; valid kinds are 'dynamixel'",
        ),
        (
            "[laser.device]\nkind = 'nxt'\nservo_ids = [1]",
            r"laser.device.servo_ids: unknown field; valid fields here are \[.*'motor_port'",
        ),
    ],
)
def test_bad_device_sections_name_the_field_and_what_is_valid(tmp_path, text, message):
    path = tmp_path / "rig.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_rig_config(path)


def test_a_config_stored_before_rig_kinds_is_the_same_wang_rig():
    # model_dump(mode="json") of the default rig as stored before configs named their kind
    stored = json.loads((Path(__file__).parent / "data" / "rig_config_layout2.json").read_text())
    assert "kind" not in stored
    config = RigConfig.model_validate(stored)
    assert config.kind == "wang"
    assert config == RigConfig()
    assert [lamp.id for lamp in config.lamps] == [lamp.id for lamp in config.light_arc.lamps]
