"""The CIGI 3.3 packet codec's machinery: a packet is a typed dataclass plus a byte layout.

A layout is a list of slots in wire order. A slot is either a plain field (``("roll", "f")``: one struct
code), padding (``(None, "3x")``) or a bit-packed word (``(None, "B", (("entity_state", 0, 2), ...))``:
bit 0 is the least significant bit, as the ICD numbers them). Both byte orders use one layout: the order
only picks struct's prefix (``>`` big-endian, ``<`` little-endian); a bit-packed word is swapped as a
whole, which is what the ICD means by "bit fields are defined within their word".

Decoding checks what the layout alone can check: floats must be finite, enumerated fields must hold one
of their values (``ENUMS``). Range checks that depend on meaning (a latitude) live with the packets.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, fields
from typing import ClassVar

BIG, LITTLE = ">", "<"
MAGIC = 0x8000  # IG Control / Start of Frame "byte swap magic": reads 0x0080 in the other byte order


class Malformed(ValueError):
    """A datagram that is rejected whole. ``kind`` is a short label for /metrics and the log."""

    def __init__(self, kind: str, detail: str):
        super().__init__(f"{kind}: {detail}")
        self.kind = kind
        self.detail = detail


Slot = tuple  # (name | None, struct code, bits | None)


@dataclass
class Packet:
    """Base of every packet. Subclasses set ID, SIZE, LAYOUT (and optionally ENUMS, NAME)."""

    ID: ClassVar[int] = 0
    SIZE: ClassVar[int] = 0
    NAME: ClassVar[str] = ""
    LAYOUT: ClassVar[list[Slot]] = []
    # field -> allowed values (enumerations whose other codes the ICD leaves undefined)
    ENUMS: ClassVar[dict[str, range | tuple]] = {}
    _structs: ClassVar[dict[str, struct.Struct]]
    _bools: ClassVar[frozenset[str]]  # the one-bit fields typed bool (the others decode as int)

    @classmethod
    def _struct(cls, order: str) -> struct.Struct:
        cached = cls.__dict__.get("_structs")
        if cached is None:
            body = "".join(slot[1] for slot in cls.LAYOUT)
            cached = {o: struct.Struct(o + "BB" + body) for o in (BIG, LITTLE)}
            size = cached[BIG].size
            if size != cls.SIZE:  # a layout that disagrees with its size is a programming error
                raise AssertionError(f"{cls.__name__}: layout is {size} bytes, SIZE says {cls.SIZE}")
            cls._structs = cached
            cls._bools = frozenset(f.name for f in fields(cls) if f.type in ("bool", bool))
        return cached[order]

    def encode(self, order: str = BIG) -> bytes:
        values: list = [self.ID, self.SIZE]
        for slot in self.LAYOUT:
            name, code = slot[0], slot[1]
            if code.endswith("x"):
                continue
            if len(slot) > 2:  # a bit-packed word
                word = 0
                for bit_name, shift, width in slot[2]:
                    word |= (int(getattr(self, bit_name)) & ((1 << width) - 1)) << shift
                values.append(word)
            else:
                values.append(getattr(self, name))
        return self._struct(order).pack(*values)

    @classmethod
    def decode(cls, data: bytes | memoryview, order: str = BIG, offset: int = 0) -> "Packet":
        """Decode one packet at ``offset`` (its id and size already checked by the caller)."""
        raw = cls._struct(order).unpack_from(data, offset)
        kwargs: dict = {}
        i = 2
        for slot in cls.LAYOUT:
            name, code = slot[0], slot[1]
            if code.endswith("x"):
                continue
            value = raw[i]
            i += 1
            if len(slot) > 2:
                for bit_name, shift, width in slot[2]:
                    bits = (value >> shift) & ((1 << width) - 1)
                    kwargs[bit_name] = bool(bits) if width == 1 and bit_name in cls._bools else bits
            else:
                if code in "fd" and not math.isfinite(value):
                    raise Malformed("non_finite", f"{cls.NAME or cls.__name__}.{name} is {value}")
                kwargs[name] = value
        for name, allowed in cls.ENUMS.items():
            if kwargs[name] not in allowed:
                raise Malformed("out_of_range", f"{cls.NAME or cls.__name__}.{name} = {kwargs[name]} "
                                                f"is not one of {list(allowed)}")
        packet = cls(**kwargs)
        packet.check()
        return packet

    def check(self) -> None:
        """Meaning-dependent ranges (raise ``Malformed("out_of_range", ...)``); none by default."""


def in_range(packet: Packet, name: str, low: float, high: float) -> None:
    value = getattr(packet, name)
    if not (low <= value <= high):
        raise Malformed("out_of_range", f"{packet.NAME}.{name} = {value} is outside [{low}, {high}]")


def f32(value: float) -> float:
    """``value`` as the float32 the wire carries (round trips compare against this)."""
    return struct.unpack("f", struct.pack("f", value))[0]
