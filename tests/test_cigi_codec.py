"""CIGI 3.3 packets: encode -> decode round trips in both byte orders, and the datagram parser's verdicts."""

from __future__ import annotations

import dataclasses
import random
import struct

import pytest

from igserver.cigi.codec import BIG, LITTLE, Malformed, f32
from igserver.cigi.datagram import build, parse, parse_ig_message
from igserver.cigi.packets_host import (HOST_PACKETS, EntityControl, IGControl, WeatherControl)
from igserver.cigi.packets_ig import IG_PACKETS, HatHotResponse, StartOfFrame

ALL = list(HOST_PACKETS.values()) + list(IG_PACKETS.values())
FLOAT_RANGES = {"lat": (-90, 90), "source_lat": (-90, 90), "destination_lat": (-90, 90), "lon": (-180, 180),
                "source_lon": (-180, 180), "destination_lon": (-180, 180), "roll": (-180, 180),
                "pitch": (-90, 90), "yaw": (0, 360), "elevation": (-90, 90), "azimuth": (0, 360),
                "humidity": (0, 100), "coverage": (0, 100), "star_intensity": (0, 100), "height": (0, 50),
                "wind_direction": (0, 360), "direction": (0, 360), "hour": (0, 23), "minute": (0, 59)}


def random_packet(cls, rng: random.Random):
    """A packet with every field random within what the layout and the ICD's ranges allow."""
    for _ in range(1000):
        packet = _random_fields(cls, rng)
        try:
            packet.check()
        except Malformed:
            continue
        return packet
    raise AssertionError(f"no valid random {cls.__name__}")


def _random_fields(cls, rng: random.Random):
    kwargs = {}
    codes = {}
    for slot in cls.LAYOUT:
        if len(slot) > 2:
            for name, _, width in slot[2]:
                codes[name] = ("bits", width)
        elif slot[0]:
            codes[slot[0]] = (slot[1], None)
    for f in dataclasses.fields(cls):
        code, width = codes[f.name]
        if f.name in ("magic",):
            continue
        if f.name == "version":
            kwargs[f.name] = 3
        elif f.name in cls.ENUMS:
            kwargs[f.name] = rng.choice(list(cls.ENUMS[f.name]))
        elif code == "bits":
            value = rng.randrange(1 << width)
            kwargs[f.name] = bool(value) if f.type in ("bool", bool) else value
        elif code in "fd":
            low, high = FLOAT_RANGES.get(f.name, (-1000.0, 1000.0))
            value = rng.uniform(low, high)
            kwargs[f.name] = f32(value) if code == "f" else value
        elif f.name in FLOAT_RANGES:
            kwargs[f.name] = rng.randint(*FLOAT_RANGES[f.name])
        else:
            bits = struct.calcsize(code) * 8
            kwargs[f.name] = rng.randrange(-(1 << bits - 1), 1 << bits - 1) if code.islower() and code != "x" \
                else rng.randrange(1 << bits)
    if cls.__name__ == "CelestialSphereControl":
        kwargs["date"] = rng.randint(1, 12) * 1_000_000 + rng.randint(1, 28) * 10_000 + 2026
    if "min_range" in kwargs:
        kwargs["min_range"], kwargs["max_range"] = sorted((abs(kwargs["min_range"]), abs(kwargs["max_range"])))
    return cls(**kwargs)


@pytest.mark.parametrize("cls", ALL, ids=lambda c: c.__name__)
@pytest.mark.parametrize("order", [BIG, LITTLE], ids=["big", "little"])
def test_round_trip(cls, order):
    rng = random.Random(cls.ID)
    for _ in range(50):
        packet = random_packet(cls, rng)
        data = packet.encode(order)
        assert len(data) == cls.SIZE and data[0] == cls.ID and data[1] == cls.SIZE
        assert cls.decode(data, order) == packet


def test_byte_orders_differ_and_both_parse():
    packets = [IGControl(host_frame=0x01020304), EntityControl(entity_id=0x0102, lat=59.9, lon=30.3, alt=12.5)]
    big, little = build(packets, BIG), build(packets, LITTLE)
    assert big != little and big[6:8] == b"\x80\x00" and little[6:8] == b"\x00\x80"
    assert parse(big).packets == parse(little).packets == packets
    assert (parse(big).order, parse(little).order) == (BIG, LITTLE)


def test_ig_message_parses():
    data = build([StartOfFrame(ig_frame=7, last_host_frame=3, ig_mode=1), HatHotResponse(request_id=2, valid=True,
                                                                                            height=1.25)])
    message = parse_ig_message(data)
    assert message.packets[0].ig_frame == 7 and message.packets[1].height == 1.25


def test_unknown_packets_skipped_and_counted():
    unknown = bytes([17, 24]) + bytes(22)  # Sensor Control: known to CIGI, not honoured here
    user = bytes([201, 8]) + bytes(6)
    data = build([IGControl()]) + unknown + user + user + EntityControl(entity_id=4).encode()
    message = parse(data)
    assert [type(p).__name__ for p in message.packets] == ["IGControl", "EntityControl"]
    assert message.unknown == {17: 1, 201: 2}


def _kind(data: bytes) -> str:
    with pytest.raises(Malformed) as info:
        parse(data)
    return info.value.kind


def test_malformed_datagrams_rejected_with_a_kind():
    good = build([IGControl(), EntityControl(entity_id=1)])
    assert _kind(good[:10]) == "short"
    assert _kind(b"") == "short"
    assert _kind(good[:-1]) == "size"  # the entity packet's size field lies about what is left
    lying = bytearray(good)
    lying[25] = 200
    assert _kind(bytes(lying)) == "size"
    zero = bytearray(good)
    zero[25] = 0
    assert _kind(bytes(zero)) == "size"
    wrong_known = bytearray(good)
    wrong_known[25] = 40
    assert _kind(bytes(wrong_known) + bytes(0)) == "size"
    assert _kind(build([EntityControl(), IGControl()])) == "first_packet"
    assert _kind(build([IGControl(), IGControl()])) == "first_packet"
    bad_magic = bytearray(good)
    bad_magic[6:8] = b"\x12\x34"
    assert _kind(bytes(bad_magic)) == "magic"
    assert _kind(build([IGControl(version=2)])) == "version"
    assert _kind(build([IGControl(), EntityControl(lat=float("nan"))])) == "non_finite"
    assert _kind(build([IGControl(), EntityControl(lon=float("inf"))])) == "non_finite"
    assert _kind(build([IGControl(), EntityControl(lat=91.0)])) == "out_of_range"
    assert _kind(build([IGControl(), EntityControl(entity_state=3)])) == "out_of_range"
    assert _kind(build([IGControl(), WeatherControl(severity=7)])) == "out_of_range"
    trailing = good + b"\x02"
    assert _kind(trailing) == "short"
