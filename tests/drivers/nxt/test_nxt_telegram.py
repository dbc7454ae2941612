"""NXT direct-command telegrams as bytes in / bytes out tables (LEGO Bluetooth
Developer Kit, Appendix 2); the expected bytes are written out by hand."""

import pytest

from drivers.nxt import (
    Opcode,
    OutputMode,
    RegulationMode,
    RunState,
    TelegramError,
    decode_battery_level,
    decode_output_state,
    decode_status,
    encode_get_battery_level,
    encode_get_output_state,
    encode_reset_motor_position,
    encode_set_output_state,
)

MOVE = OutputMode.MOTORON | OutputMode.BRAKE | OutputMode.REGULATED


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        # port A, +75 %, on+brake+regulated, speed regulation, RUNNING, 360° limit
        (
            dict(
                port=0,
                power=75,
                mode=MOVE,
                regulation=RegulationMode.MOTOR_SPEED,
                run_state=RunState.RUNNING,
                tacho_limit=360,
            ),
            "00 04 00 4b 07 01 00 20 68 01 00 00",
        ),
        # port A, −30 % (two's complement 0xe2), 288° limit
        (
            dict(
                port=0,
                power=-30,
                mode=MOVE,
                regulation=RegulationMode.MOTOR_SPEED,
                run_state=RunState.RUNNING,
                tacho_limit=288,
            ),
            "00 04 00 e2 07 01 00 20 20 01 00 00",
        ),
        # port B at constant 100 %, unregulated, no limit (the laser diode)
        (
            dict(
                port=1,
                power=100,
                mode=OutputMode.MOTORON,
                regulation=RegulationMode.IDLE,
                run_state=RunState.RUNNING,
            ),
            "00 04 01 64 01 00 00 20 00 00 00 00",
        ),
        # port B off: coast, idle
        (
            dict(
                port=1,
                power=0,
                mode=OutputMode.COAST,
                regulation=RegulationMode.IDLE,
                run_state=RunState.IDLE,
            ),
            "00 04 01 00 00 00 00 00 00 00 00 00",
        ),
        # no reply wanted, turn ratio −100, largest tacho limit
        (
            dict(
                port=2,
                power=-100,
                mode=MOVE,
                regulation=RegulationMode.MOTOR_SYNC,
                turn_ratio=-100,
                run_state=RunState.RAMPUP,
                tacho_limit=0xFFFFFFFF,
                reply=False,
            ),
            "80 04 02 9c 07 02 9c 10 ff ff ff ff",
        ),
    ],
)
def test_set_output_state_bytes(kwargs, expected):
    port = kwargs.pop("port")
    assert encode_set_output_state(port, **kwargs).hex(" ") == expected


@pytest.mark.parametrize(
    ("telegram", "expected"),
    [
        (encode_get_output_state(0), "00 06 00"),
        (encode_get_output_state(2), "00 06 02"),
        (encode_reset_motor_position(0, relative=False), "00 0a 00 00"),
        (encode_reset_motor_position(1, relative=True), "00 0a 01 01"),
        (encode_reset_motor_position(0, relative=True, reply=False), "80 0a 00 01"),
        (encode_get_battery_level(), "00 0b"),
    ],
)
def test_request_bytes(telegram, expected):
    assert telegram.hex(" ") == expected


@pytest.mark.parametrize(
    ("bad", "field"),
    [
        (dict(power=101), "power 101"),
        (dict(power=-101), "power -101"),
        (dict(turn_ratio=120), "turn_ratio 120"),
        (dict(tacho_limit=-1), "tacho_limit -1"),
        (dict(tacho_limit=2**32), "tacho_limit 4294967296"),
        (dict(port=3), "output port 3"),
    ],
)
def test_set_output_state_rejects_out_of_range(bad, field):
    args = dict(
        port=0,
        power=50,
        mode=MOVE,
        regulation=RegulationMode.MOTOR_SPEED,
        run_state=RunState.RUNNING,
        tacho_limit=10,
    )
    args.update(bad)
    port = args.pop("port")
    with pytest.raises(TelegramError, match=field) as info:
        encode_set_output_state(port, **args)
    assert not info.value.malformed


def test_output_state_reply_decodes_every_field():
    reply = bytes.fromhex(
        "02 06 00"  # reply, opcode, status ok
        "00 e2 07 01 00 20"  # port A, power −30, mode 7, speed regulation, turn 0, RUNNING
        "20 01 00 00"  # tacho limit 288
        "9c ff ff ff"  # tacho count −100
        "0a 00 00 00"  # block tacho count 10
        "00 00 00 80"  # rotation count −2**31
    )
    state = decode_output_state(reply)
    assert (state.port, state.power, state.turn_ratio) == (0, -30, 0)
    assert state.mode == MOVE
    assert state.regulation == RegulationMode.MOTOR_SPEED
    assert state.run_state == RunState.RUNNING
    assert (state.tacho_limit, state.tacho_count) == (288, -100)
    assert (state.block_tacho_count, state.rotation_count) == (10, -(2**31))


@pytest.mark.parametrize(
    ("reply", "mv"), [("02 0b 00 d0 20", 8400), ("02 0b 00 64 19", 6500), ("02 0b 00 00 00", 0)]
)
def test_battery_reply(reply, mv):
    assert decode_battery_level(bytes.fromhex(reply)) == mv


@pytest.mark.parametrize(
    ("reply", "opcode", "length", "malformed", "match"),
    [
        ("02 04", Opcode.SET_OUTPUT_STATE, 3, True, "2 bytes, expected 3"),
        ("03 04 00", Opcode.SET_OUTPUT_STATE, 3, True, "starts 03 04, expected 02 04"),
        ("02 06 00", Opcode.SET_OUTPUT_STATE, 3, True, "starts 02 06, expected 02 04"),
        ("02 0b 00 d0", Opcode.GET_BATTERY_LEVEL, 5, True, "4 bytes, expected 5"),
        ("02 04 c0", Opcode.SET_OUTPUT_STATE, 3, False, "0xc0 .data contains out-of-range"),
        ("02 0a f0", Opcode.RESET_MOTOR_POSITION, 3, False, "0xf0 .bad input or output"),
        ("02 0b 77 00 00", Opcode.GET_BATTERY_LEVEL, 5, False, "0x77 .unknown status"),
    ],
)
def test_bad_replies_are_named(reply, opcode, length, malformed, match):
    with pytest.raises(TelegramError, match=match) as info:
        decode_status(bytes.fromhex(reply), opcode, length=length)
    assert info.value.malformed is malformed


def test_output_state_with_impossible_regulation_is_malformed():
    reply = bytes.fromhex("02 06 00 00 00 00 07 00 00" + "00" * 16)
    with pytest.raises(TelegramError, match="regulation mode 7") as info:
        decode_output_state(reply)
    assert info.value.malformed
