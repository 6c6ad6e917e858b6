"""A minimal pcap writer: UDP datagrams in IPv4/Ethernet frames, for Wireshark/tshark to decode.

Only what a capture of CIGI traffic needs (no options, no IPv6): the classic libpcap format
(magic 0xa1b2c3d4, microsecond stamps, link type 1 = Ethernet), checksums left at zero where
allowed (UDP) and computed where required (IPv4 header).
"""

from __future__ import annotations

import socket
import struct
import threading
import time
from pathlib import Path


def _ip_checksum(header: bytes) -> int:
    total = sum(struct.unpack(f">{len(header) // 2}H", header))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF


def udp_frame(payload: bytes, src: tuple[str, int], dst: tuple[str, int]) -> bytes:
    udp = struct.pack(">HHHH", src[1], dst[1], 8 + len(payload), 0) + payload
    ip = struct.pack(">BBHHHBBH4s4s", 0x45, 0, 20 + len(udp), 0, 0x4000, 64, 17, 0,
                     socket.inet_aton(src[0]), socket.inet_aton(dst[0]))
    ip = ip[:10] + struct.pack(">H", _ip_checksum(ip)) + ip[12:]
    ethernet = b"\x02\x00\x00\x00\x00\x02" + b"\x02\x00\x00\x00\x00\x01" + b"\x08\x00"
    return ethernet + ip + udp


class PcapWriter:
    """``with PcapWriter(path) as pcap: pcap.add(payload, src, dst)``."""

    def __init__(self, path: str | Path):
        self._file = open(path, "wb")
        self._lock = threading.Lock()  # a host's sender and receiver threads write to one capture
        self._file.write(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1))

    def add(self, payload: bytes, src: tuple[str, int], dst: tuple[str, int], stamp: float | None = None) -> None:
        frame = udp_frame(payload, src, dst)
        stamp = time.time() if stamp is None else stamp
        seconds = int(stamp)
        with self._lock:
            self._file.write(struct.pack("<IIII", seconds, int((stamp - seconds) * 1e6), len(frame), len(frame)))
            self._file.write(frame)

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> "PcapWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
