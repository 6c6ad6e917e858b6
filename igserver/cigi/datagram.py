"""Datagrams: one UDP datagram is one CIGI message, a run of packets each led by (id, size).

A host message starts with IG Control, an IG message with Start of Frame; that first packet's magic
number (0x8000) tells the sender's byte order, and the rest of the message is read in it. Packets this
IG does not know are skipped by their size field and counted per id; anything else wrong rejects the
whole datagram (``Malformed``) before any of it is applied.
"""

from __future__ import annotations

import struct
from collections import Counter
from dataclasses import dataclass, field

from .codec import BIG, LITTLE, MAGIC, Malformed, Packet
from .packets_host import HOST_PACKETS, IGControl
from .packets_ig import IG_PACKETS, StartOfFrame

MAX_DATAGRAM = 65_507  # bytes, the largest UDP payload over IPv4
MIN_PACKET = 4  # bytes: an id, a size and at least two more; CIGI 3 sizes are multiples of 8 anyway


@dataclass
class Message:
    order: str  # BIG or LITTLE
    packets: list[Packet]
    unknown: Counter = field(default_factory=Counter)  # packet id -> how many were skipped


def byte_order(data: bytes, first: type[Packet]) -> str:
    """The sender's byte order from the first packet's magic number (bytes 6-7)."""
    if len(data) < first.SIZE:
        raise Malformed("short", f"{len(data)} bytes; a message starts with a {first.SIZE}-byte {first.NAME}")
    if data[0] != first.ID:
        raise Malformed("first_packet", f"first packet id {data[0]}, expected {first.ID} ({first.NAME})")
    if data[1] != first.SIZE:
        raise Malformed("size", f"{first.NAME} size field {data[1]}, expected {first.SIZE}")
    magic = struct.unpack_from(">H", data, 6)[0]
    if magic == MAGIC:
        return BIG
    if magic == 0x0080:
        return LITTLE
    raise Malformed("magic", f"magic number 0x{magic:04x}, expected 0x8000 in either byte order")


def parse(data: bytes, table: dict[int, type[Packet]] = HOST_PACKETS,
          first: type[Packet] = IGControl) -> Message:
    """Split and decode a whole datagram; raises ``Malformed`` for anything that is not a valid message."""
    if len(data) > MAX_DATAGRAM:
        raise Malformed("size", f"{len(data)} bytes is larger than a UDP datagram")
    order = byte_order(data, first)
    packets: list[Packet] = []
    unknown: Counter = Counter()
    offset, end = 0, len(data)
    while offset < end:
        if end - offset < 2:
            raise Malformed("short", f"{end - offset} byte(s) left at offset {offset}: no room for a packet header")
        packet_id, size = data[offset], data[offset + 1]
        if size < MIN_PACKET or offset + size > end:
            raise Malformed("size", f"packet {packet_id} at offset {offset} says {size} bytes; "
                                    f"{end - offset} are left")
        cls = table.get(packet_id)
        if cls is None:
            unknown[packet_id] += 1
        else:
            if size != cls.SIZE:
                raise Malformed("size", f"{cls.NAME} at offset {offset} says {size} bytes, it is {cls.SIZE}")
            if offset and cls is first:
                raise Malformed("first_packet", f"a second {first.NAME} at offset {offset}")
            packets.append(cls.decode(data, order, offset))
        offset += size
    return Message(order, packets, unknown)


def parse_ig_message(data: bytes) -> Message:
    """An IG message (what the host emulator and the tests read): Start of Frame first."""
    return parse(data, IG_PACKETS, StartOfFrame)


def build(packets: list[Packet], order: str = BIG) -> bytes:
    """One datagram of ``packets`` in ``order`` (the first must be IG Control or Start of Frame)."""
    return b"".join(packet.encode(order) for packet in packets)
