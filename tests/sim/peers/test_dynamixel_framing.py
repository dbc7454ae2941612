"""Protocol 2.0 framing of the bus emulator: bytes in, bytes out.

Known-good packets are the ROBOTIS e-manual's examples; the CRC is also
checked against dynamixel-sdk's independent implementation.
"""

import dynamixel_sdk as sdk
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sim.peers.dynamixel import PacketReader, crc16, encode, encode_status
from sim.peers.dynamixel._framing import stuff, unstuff


def h(text: str) -> bytes:
    return bytes.fromhex(text)


# (servo id, instruction, params) → the packet on the wire (e-manual examples)
INSTRUCTIONS = [
    (0x01, 0x01, "", "FF FF FD 00 01 03 00 01 19 4E"),  # PING id 1
    (0x01, 0x02, "84 00 04 00", "FF FF FD 00 01 07 00 02 84 00 04 00 1D 15"),  # READ 132, 4
    (  # WRITE 116 (goal position) = 512
        0x01,
        0x03,
        "74 00 00 02 00 00",
        "FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89",
    ),
    (0x01, 0x08, "", "FF FF FD 00 01 03 00 08 2F 4E"),  # REBOOT id 1
]
STATUSES = [
    # PING status: model 1030 (0x0406), firmware 38 (0x26)
    (0x01, 0x00, "06 04 26", "FF FF FD 00 01 07 00 55 00 06 04 26 65 5D"),
    # READ status: present position 166 (0xA6)
    (0x01, 0x00, "A6 00 00 00", "FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0"),
    # WRITE status: no error, no parameters
    (0x01, 0x00, "", "FF FF FD 00 01 04 00 55 00 A1 0C"),
]


@pytest.mark.parametrize(("servo_id", "instruction", "params", "wire"), INSTRUCTIONS)
def test_instruction_packets(servo_id, instruction, params, wire):
    assert encode(servo_id, instruction, h(params)) == h(wire)


@pytest.mark.parametrize(("servo_id", "error", "params", "wire"), STATUSES)
def test_status_packets(servo_id, error, params, wire):
    assert encode_status(servo_id, error, h(params)) == h(wire)


@pytest.mark.parametrize(("servo_id", "instruction", "params", "wire"), INSTRUCTIONS)
def test_reader_decodes_the_known_packets(servo_id, instruction, params, wire):
    (packet,) = PacketReader().feed(h(wire))
    assert (packet.servo_id, packet.instruction, packet.params, packet.crc_ok) == (
        servo_id,
        instruction,
        h(params),
        True,
    )


STUFFING = [
    ("FF FF FD", "FF FF FD FD"),
    ("01 FF FF FD 02", "01 FF FF FD FD 02"),
    ("FF FF FD FF FF FD", "FF FF FD FD FF FF FD FD"),
    ("FF FF FE", "FF FF FE"),
    ("FF FD FF", "FF FD FF"),
]


@pytest.mark.parametrize(("body", "stuffed"), STUFFING)
def test_byte_stuffing_table(body, stuffed):
    assert stuff(h(body)) == h(stuffed)
    assert unstuff(h(stuffed)) == h(body)


def test_a_stuffed_packet_counts_the_stuffed_length():
    # WRITE of FF FF FD to address 0x0100: the body gets one extra FD, the length says so.
    wire = encode(1, 0x03, h("00 01 FF FF FD"))
    assert wire[:7] == h("FF FF FD 00 01 09 00")  # INST + 6 stuffed params + CRC
    assert wire[7:-2] == h("03 00 01 FF FF FD FD")
    (packet,) = PacketReader().feed(wire)
    assert packet.params == h("00 01 FF FF FD")


@given(st.binary(max_size=64))
def test_crc_matches_the_sdk(data):
    assert crc16(data) == sdk.PacketHandler(2.0).updateCRC(0, list(data), len(data))


@given(
    st.integers(0, 0xFD),
    st.sampled_from([0x01, 0x02, 0x03, 0x08, 0x82, 0x83]),
    st.binary(max_size=40),
    st.binary(max_size=8).filter(lambda b: b"\xff\xff\xfd" not in b),
    st.integers(1, 7),
)
def test_round_trip_through_noise_and_split_reads(servo_id, instruction, params, noise, cut):
    wire = noise + encode(servo_id, instruction, params) + encode(servo_id, 0x01)
    reader = PacketReader()
    packets = []
    for start in range(0, len(wire), cut):  # arrives in small pieces
        packets.extend(reader.feed(wire[start : start + cut]))
    assert [(p.servo_id, p.instruction, p.params, p.crc_ok) for p in packets] == [
        (servo_id, instruction, params, True),
        (servo_id, 0x01, b"", True),
    ]


def test_a_damaged_packet_is_flagged_and_the_next_one_still_read():
    bad = bytearray(h("FF FF FD 00 01 07 00 02 84 00 04 00 1D 15"))
    bad[-1] ^= 0xFF
    packets = list(PacketReader().feed(bytes(bad) + h("FF FF FD 00 01 03 00 01 19 4E")))
    assert [(p.instruction, p.crc_ok) for p in packets] == [(0x02, False), (0x01, True)]


def test_a_nonsense_length_is_skipped():
    garbage = h("FF FF FD 00 01 FF FF")  # length 65535: not a packet
    (packet,) = PacketReader().feed(garbage + h("FF FF FD 00 01 03 00 01 19 4E"))
    assert packet.instruction == 0x01
