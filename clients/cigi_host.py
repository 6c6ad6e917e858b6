"""A small CIGI 3.3 host: plays a scenario against igserver's CIGI port and prints what the IG answers.

    .venv/bin/python clients/cigi_host.py [--ig 127.0.0.1] [--port 8004] [--listen 8005] [--seconds 10]
        [--rate 60] [--sync] [--little-endian] [--hour 12] [--pcap capture.pcap]

Start the IG with ``igserver serve --cigi``. The scenario: the ownship (entity 1, a patrol boat) sails
north at 10 m/s with the eyepoint behind and above it; the time of day runs from --hour at one minute a
second; at 1 s the visibility drops and rain starts; at 2 s a crate (entity 2) appears ahead and a fire is
started on it by Component Control; HAT/HOT requests under the ownship go out at 10 Hz. It prints the
Start of Frame rate, the IG mode and frame counters, and the HAT/HOT answers: the tool to check that an
installation speaks CIGI. ``--sync`` marks the timestamps valid (the host's frames then drive sim_time)
and runs in lockstep: each host frame is sent when the IG's next Start of Frame has arrived.
"""

from __future__ import annotations

import argparse
import socket
import sys
import threading
import time
from collections import Counter
from dataclasses import dataclass, field

from igserver.cigi.codec import BIG, LITTLE, Malformed
from igserver.cigi.datagram import build, parse_ig_message
from igserver.cigi.packets_host import (AtmosphereControl, CelestialSphereControl, ComponentControl, EntityControl,
                                        HatHotRequest, IGControl, ViewControl, WeatherControl)
from igserver.cigi.packets_ig import HatHotExtendedResponse, HatHotResponse, StartOfFrame

LAT0, LON0 = 59.93, 30.31  # the default scene's location
M_PER_DEG_LAT = 111_412.0  # m per degree of latitude near 60° N (enough for a demo course)
FIRE_ON = 0x3F800000  # float32 1.0 as a data word


@dataclass
class Summary:
    sof: list[StartOfFrame] = field(default_factory=list)
    sof_times: list[float] = field(default_factory=list)  # monotonic s of each SOF's arrival
    responses: list = field(default_factory=list)
    counts: Counter = field(default_factory=Counter)
    errors: Counter = field(default_factory=Counter)
    sof_arrived: threading.Event = field(default_factory=threading.Event)

    def sof_rate(self) -> float:
        """Hz over the SOFs received (0 when fewer than two)."""
        if len(self.sof_times) < 2:
            return 0.0
        return (len(self.sof_times) - 1) / (self.sof_times[-1] - self.sof_times[0])


def scenario(frame: int, rate: float, hour: int, sync: bool) -> list:
    """The packets of host frame ``frame`` (after its IG Control)."""
    t = frame / rate
    north = 10.0 * t  # m: the ownship sails north at 10 m/s
    packets: list = [EntityControl(entity_id=1, entity_type=1, lat=LAT0 + north / M_PER_DEG_LAT, lon=LON0, yaw=0.0)]
    if frame == 0:
        packets.append(ViewControl(view_id=0, entity_id=1, x=-40.0, y=0.0, z=-12.0, pitch=-8.0))
    if frame % int(rate) == 0:  # once a second: the time of day, one minute on
        minutes = hour * 60 + int(t)
        packets.append(CelestialSphereControl(hour=minutes // 60 % 24, minute=minutes % 60))
    if frame == int(rate):
        packets.append(AtmosphereControl(visibility=3000.0, humidity=70, horizontal_wind=8.0, wind_direction=200.0))
        packets.append(WeatherControl(layer_id=4, weather_enable=True, severity=2))
    if frame == 2 * int(rate):
        packets.append(EntityControl(entity_id=2, entity_type=3, lat=LAT0 + (north + 60.0) / M_PER_DEG_LAT,
                                     lon=LON0, alt=0.0))
        packets.append(ComponentControl(component_class=0, component_id=1, instance_id=2, component_state=1,
                                        data1=0, data2=0x40000000, data3=FIRE_ON))  # fire, 2 m, intensity 1
    if frame % max(int(rate / 10), 1) == 0:  # HAT/HOT under the ownship at 10 Hz
        packets.append(HatHotRequest(request_id=frame & 0xFFFF, request_type=2, entity_relative=True,
                                     entity_id=1, lat=0.0, lon=0.0, alt=0.0))
    return packets


def receive(sock: socket.socket, summary: Summary, stop: threading.Event, verbose: bool, capture=None) -> None:
    sock.settimeout(0.1)
    while not stop.is_set():
        try:
            data, sender = sock.recvfrom(65536)
        except (socket.timeout, OSError):
            continue
        if capture is not None:
            capture.add(data, sender[:2], sock.getsockname()[:2])
        try:
            message = parse_ig_message(data)
        except Malformed as exc:
            summary.errors[exc.kind] += 1
            continue
        for packet in message.packets:
            summary.counts[packet.NAME] += 1
            if isinstance(packet, StartOfFrame):
                summary.sof.append(packet)
                summary.sof_times.append(time.monotonic())
                summary.sof_arrived.set()
            elif isinstance(packet, (HatHotResponse, HatHotExtendedResponse)):
                summary.responses.append(packet)
                if verbose:
                    print(f"  HAT/HOT #{packet.request_id}: " + (
                        f"HAT {packet.hat:.3f} m, HOT {packet.hot:.3f} m, normal az {packet.normal_azimuth:.1f}"
                        f" el {packet.normal_elevation:.1f}" if isinstance(packet, HatHotExtendedResponse)
                        else f"{packet.height:.3f} m") + ("" if packet.valid else " (invalid)"))


def run(ig: tuple[str, int], listen_port: int = 8005, seconds: float = 10.0, rate: float = 60.0,
        sync: bool = False, order: str = BIG, hour: int = 12, capture=None, verbose: bool = False,
        sock: socket.socket | None = None, extra=None, first_frame: int = 0) -> Summary:
    """Play the scenario for ``seconds``; ``sock``: an already bound socket (tests); ``extra(frame)``:
    more packets for a frame (tests); ``first_frame``: the host frame number of the first frame."""
    own = sock is None
    if own:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1" if ig[0] in ("127.0.0.1", "localhost") else "0.0.0.0", listen_port))
    summary, stop = Summary(), threading.Event()
    reader = threading.Thread(target=receive, args=(sock, summary, stop, verbose, capture), daemon=True)
    reader.start()
    start = time.monotonic()
    frame = 0
    try:
        while frame < seconds * rate:
            packets = [IGControl(host_frame=(first_frame + frame) & 0xFFFFFFFF, ig_mode=1, timestamp_valid=sync,
                                 timestamp=int(frame / rate * 100_000) & 0xFFFFFFFF)]
            packets += scenario(frame, rate, hour, sync) + (list(extra(frame)) if extra else [])
            data = build(packets, order)
            summary.sof_arrived.clear()
            sock.sendto(data, ig)
            if capture is not None:
                capture.add(data, sock.getsockname()[:2], ig)
            frame += 1
            if sync:  # synchronous: the next host frame answers the IG's next Start of Frame
                summary.sof_arrived.wait(2.0)
            else:
                time.sleep(max(0.0, start + frame / rate - time.monotonic()))
        time.sleep(0.3)  # the answers to the last requests
    finally:
        stop.set()
        reader.join(1.0)
        if own:
            sock.close()
    return summary


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ig", default="127.0.0.1", help="the IG's address")
    ap.add_argument("--port", type=int, default=8004, help="the IG's CIGI port")
    ap.add_argument("--listen", type=int, default=8005, help="the port IG messages come to")
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=60.0, help="host frames per second")
    ap.add_argument("--sync", action="store_true", help="timestamps valid: the host's frames drive sim_time")
    ap.add_argument("--little-endian", action="store_true", help="send in little-endian byte order")
    ap.add_argument("--hour", type=int, default=12, help="UTC hour the scenario starts at")
    ap.add_argument("--pcap", help="also write what was sent and received to this pcap file")
    ap.add_argument("-q", "--quiet", action="store_true", help="only the summary")
    args = ap.parse_args(argv)
    capture = None
    if args.pcap:
        from igserver.cigi.pcap import PcapWriter

        capture = PcapWriter(args.pcap)
    try:
        summary = run((args.ig, args.port), args.listen, args.seconds, args.rate, args.sync,
                      LITTLE if args.little_endian else BIG, args.hour, capture, not args.quiet)
    finally:
        if capture is not None:
            capture.close()
    last = summary.sof[-1] if summary.sof else None
    modes = Counter("operate" if s.ig_mode == 1 else "standby" for s in summary.sof)
    print(f"SOF: {len(summary.sof)} at {summary.sof_rate():.1f} Hz; modes {dict(modes)}"
          + (f"; last IG frame {last.ig_frame}, last host frame {last.last_host_frame}" if last else ""))
    print(f"HAT/HOT answers: {len(summary.responses)}; packets {dict(summary.counts)}"
          + (f"; malformed {dict(summary.errors)}" if summary.errors else ""))
    return 0 if summary.sof else 1


if __name__ == "__main__":
    sys.exit(main())
